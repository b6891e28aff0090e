"""trim: per-pixel rank trimming."""
from __future__ import annotations

import numpy as np
import pytest

import psbench as ps

from psbench import PsbenchError
from psbench.solve.methods.trim import TrimOptions

from _acceptance import errors
from _robust_scenes import fit, lambert_scene, problem


@pytest.mark.xfail(strict=True, reason="measured 0.48 / 0.43 / 0.60 deg (mean 0.50): the "
                   "25 % bright drop misses pixels with five or more 3x outliers of 16 "
                   "and 3x copies of dim observations that stay below the top four")
def test_sparse_corruptions_acceptance():
    res = errors(lambda p: fit("trim", p))
    assert all(l2 > 3.0 for l2, _ in res)
    assert np.mean([e for _, e in res]) < 0.5, res


def test_sparse_corruptions_much_better_than_least_squares():
    for l2, e in errors(lambda p: fit("trim", p)):
        assert e < 0.05 * l2


def distinct_images():
    """16 rig images of random albedo-scaled normals: no two intensities equal."""
    lay = ps.layout("30x8+60x8")
    rng = np.random.default_rng(0)
    n = rng.normal(size=(16, 16, 3)) * [0.15, 0.15, 1.0]
    n[..., 2] = np.abs(n[..., 2]) + 1.0
    images = np.einsum("kc,hwc->khw", lay.S, n).astype(np.float32)
    assert (images > 0).all()
    return lay, images


def test_drops_the_requested_ranks():
    lay, images = distinct_images()
    f = fit("trim", problem(images, lay), drop_dark=0.25, drop_bright=0.125)
    kept = f.valid.sum(axis=0)
    assert (kept == 16 - 4 - 2).all()
    order = np.argsort(np.argsort(images, axis=0), axis=0)     # ranks 0..15
    assert (f.valid == ((order >= 4) & (order < 14))).all()


def test_ties_with_a_dropped_value_go_with_it():
    """A run of zeros (shadow) is one level: all of it is dropped."""
    surf, lay, images = lambert_scene(16)
    images = images.copy()
    images[:6] = 0.0
    f = fit("trim", problem(images, lay, object_mask=surf.mask))
    assert not f.valid[:6].any() and f.valid[6:].sum(axis=0).min() >= 3


def test_ranks_among_valid_observations_and_keeps_three():
    lay, images = distinct_images()
    valid = np.ones(images.shape, dtype=bool)
    valid[:8] = False                                            # 8 valid left
    f = fit("trim", problem(images, lay, valid=valid))
    assert not f.valid[:8].any() and (f.valid.sum(axis=0) == 4).all()
    ranks = np.argsort(np.argsort(images[8:], axis=0), axis=0)
    assert (f.valid[8:] == ((ranks >= 2) & (ranks < 6))).all()
    valid[8:12] = False                                          # 4 valid: keep 3
    f = fit("trim", problem(images, lay, valid=valid), drop_dark=0.4, drop_bright=0.4)
    assert (f.valid.sum(axis=0) == 3).all()


@pytest.mark.parametrize("kw", [{"drop_dark": 0.5}, {"drop_dark": -0.01},
                                {"drop_bright": 0.7}, {"drop_bright": "a"}])
def test_fractions_in_range(kw):
    with pytest.raises(PsbenchError, match=rf"{next(iter(kw))} must be a number in \[0, 0.5\)"):
        TrimOptions(**kw)
