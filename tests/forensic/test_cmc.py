"""Congruent matching cells on synthetic topographies with a known pose."""
import cv2
import numpy as np
import pytest

from psbench._shared.checks import PsbenchError
from psbench.forensic import cmc
from psbench.forensic.cmc import CMC_THRESHOLD

PIXEL = 6.25


def _field(seed, size=256):
    """Band-limited random heights (µm) on a disc, like a breech face."""
    rng = np.random.default_rng(seed)
    z = cv2.GaussianBlur(rng.standard_normal((size, size)).astype(np.float32), (0, 0), 2.0)
    yy, xx = np.mgrid[:size, :size] - (size - 1) / 2
    valid = np.hypot(yy, xx) < 0.47 * size
    return z, valid


def _moved(z, valid, angle=0.0, shift=(0.0, 0.0)):
    size = z.shape[0]
    M = cv2.getRotationMatrix2D(((size - 1) / 2, (size - 1) / 2), angle, 1.0)
    M[:, 2] += shift
    zb = cv2.warpAffine(z, M, (size, size), flags=cv2.INTER_CUBIC)
    vb = cv2.warpAffine(valid.astype(np.float32), M, (size, size)) > 0.999
    return np.where(vb, zb, np.nan).astype(np.float32), vb


@pytest.mark.parametrize("angle, shift", [(0.0, (7.0, -5.0)), (6.0, (0.0, 0.0)),
                                          (-9.0, (4.0, 3.0))])
def test_pose_recovered_and_count_high(angle, shift):
    z, v = _field(0)
    zb, vb = _moved(z, v, angle, shift)
    r = cmc(z, zb, v, vb, pixel_size=PIXEL)
    n = len(r.cells)
    assert n >= 40
    assert r.count >= 0.8 * n
    assert r.match
    # b is a turned by +angle then shifted: laying b on a turns it back by -angle
    assert abs(r.pose.theta + angle) <= 1.0
    # pose.matrix (b's pixels -> a's) undoes the warp that made b, within a pixel
    size = z.shape[0]
    M = cv2.getRotationMatrix2D(((size - 1) / 2, (size - 1) / 2), angle, 1.0)
    M[:, 2] += shift
    corners = np.float64([[20, 20, 1], [235, 20, 1], [20, 235, 1], [235, 235, 1]]).T
    made = M @ corners
    back = r.pose.matrix @ np.vstack([made, np.ones(4)])
    assert np.abs(back - corners[:2]).max() <= 1.5
    assert r.ccf > 0.9
    assert set(r.cells.columns) >= {"row", "col", "ccf", "dx", "dy", "theta", "congruent"}


def test_unrelated_fields_count_low():
    counts, ccfs = [], []
    for s in range(3):
        z, v = _field(10 + s)
        zb, vb = _field(20 + s)
        r = cmc(z, zb, v, vb, pixel_size=PIXEL)
        counts.append(r.count)
        ccfs.append(r.ccf)
    assert max(counts) < CMC_THRESHOLD
    assert max(ccfs) < 0.3


def test_noise_on_a_copy_keeps_it_a_match():
    z, v = _field(1)
    zb, vb = _moved(z, v, 3.0, (2.0, 2.0))
    rng = np.random.default_rng(5)
    zb = zb + 0.5 * float(np.nanstd(zb)) * rng.standard_normal(zb.shape).astype(np.float32)
    r = cmc(z, zb, v, vb, pixel_size=PIXEL)
    assert r.count >= CMC_THRESHOLD


def test_filtered_skips_the_bandpass_and_tolerances_matter():
    z, v = _field(2)
    zb, vb = _moved(z, v, 0.0, (5.0, 0.0))
    loose = cmc(z, zb, v, vb, pixel_size=PIXEL, filtered=True)
    tight = cmc(z, zb, v, vb, pixel_size=PIXEL, filtered=True, min_ccf=0.999)
    assert loose.count > tight.count


@pytest.mark.parametrize("kwargs, match", [
    ({"pixel_size": 0}, "pixel_size"),
    ({"pixel_size": PIXEL, "cells": (0, 8)}, "cells"),
    ({"pixel_size": PIXEL, "cells": (80, 80)}, "cells"),
    ({"pixel_size": PIXEL, "min_valid": 0}, "min_valid"),
    ({"pixel_size": PIXEL, "angles": []}, "angles"),
    ({"pixel_size": PIXEL, "translation_tol": -1}, "translation_tol"),
    ({"pixel_size": PIXEL, "min_ccf": 2}, "min_ccf"),
    ({"pixel_size": PIXEL, "region": 1}, "region"),
])
def test_bad_options(kwargs, match):
    z, v = _field(3, 96)
    with pytest.raises(PsbenchError, match=match):
        cmc(z, z, v, v, **kwargs)


def test_bad_arrays():
    z, v = _field(3, 96)
    with pytest.raises(PsbenchError, match="height_a"):
        cmc(z[0], z, pixel_size=PIXEL)
    with pytest.raises(PsbenchError, match="valid_b"):
        cmc(z, z, v, v[:10], pixel_size=PIXEL)
    with pytest.raises(PsbenchError, match="64 pixels"):
        cmc(z, np.full_like(z, np.nan), pixel_size=PIXEL)
