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
    # at the method's design scale: 8 x 8 cells of ~65 px on a 512 px face (cmcR's 6.25 um
    # working resolution, a 3.2 mm breech face), each cell holding ~80 independent samples
    # of the field, so chance correlations stay below min_ccf = 0.5 (on 256 px fields the
    # cells hold ~20 and most reach 0.5 by chance: see psbench.forensic.cmc's notes)
    counts, ccfs = [], []
    for s in range(2):
        z, v = _field(10 + s, 512)
        zb, vb = _field(20 + s, 512)
        r = cmc(z, zb, v, vb, pixel_size=PIXEL)
        counts.append(r.count)
        ccfs.append(r.ccf)
    assert max(counts) <= 1
    assert max(ccfs) < 0.3


def test_a_field_against_itself_moved_gives_all_cells():
    z, v = _field(4, 512)
    zb, vb = _moved(z, v, -6.0, (9.0, -4.0))
    r = cmc(z, zb, v, vb, pixel_size=PIXEL)
    inside = r.cells[r.cells.valid >= 0.5]       # cells whose data lie on the moved copy
    assert inside.congruent.all()
    assert r.count >= 0.9 * len(r.cells)


def test_coarse_search_finds_the_exhaustive_poses():
    z, v = _field(5)
    zb, vb = _moved(z, v, 4.0, (3.0, 6.0))
    fast = cmc(z, zb, v, vb, pixel_size=PIXEL)
    full = cmc(z, zb, v, vb, pixel_size=PIXEL, coarse=1)
    assert abs(fast.count - full.count) <= 2
    # cells with most of their area on data (edge cells hold too little to pin a pose)
    c = fast.cells.congruent & full.cells.congruent & (full.cells.valid >= 0.5)
    assert c.sum() >= 0.8 * (full.cells.valid >= 0.5).sum()
    for k in ("dx", "dy"):
        assert (fast.cells[k][c] - full.cells[k][c]).abs().max() <= 1
    assert (fast.cells.theta[c] - full.cells.theta[c]).abs().max() <= 3
    assert abs(fast.ccf - full.ccf) < 0.01


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
    ({"pixel_size": PIXEL, "coarse": 0}, "coarse"),
    ({"pixel_size": PIXEL, "refine": -1}, "refine"),
    ({"pixel_size": PIXEL, "workers": 0}, "workers"),
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


def test_refinement_regions_equal_the_whole_rotated_frame():
    from psbench.forensic import _cmc_search as ccs

    z, v = _field(2)
    zm = ccs.stacked(z, v)
    frame = (z.shape[0] + 40, z.shape[1] + 40)
    cb, ca = (0.5 * z.shape[1] - 0.3, 0.5 * z.shape[0] + 0.2), (0.5 * frame[1], 0.5 * frame[0])
    rows, cols = np.array([3, 50, 101]), np.array([17, 0, 88])
    for theta in (-7.5, 0.0, 12.0):
        B, MB, _ = ccs.rotated(zm, theta, cb, ca, frame)
        pb, pm = ccs.patches(zm, theta, cb, ca, rows, cols, (30, 41))
        for i, (r, c) in enumerate(zip(rows, cols)):
            # the same warp up to OpenCV's 1/32 px grid of source positions, on which a
            # shifted matrix may round a few pixels the other way
            d = np.abs(pb[i] - B[r:r + 30, c:c + 41])
            assert (d < 1e-5).mean() > 0.95 and d.max() < 0.05 * z[v].std()
            assert (pm[i] == MB[r:r + 30, c:c + 41]).mean() > 0.99
