"""trim: per-pixel rank trimming."""
from __future__ import annotations

import numpy as np
import pytest

import psbench as ps

from psbench import PsbenchError
from psbench.solve.methods.robust.trim import TrimOptions

from _acceptance import errors
from _robust_scenes import fit, lambert_scene, problem


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
    """Fractions of the m - 3 redundant observations, rounded: 16 lights, 0.25 / 0.1 ->
    round(3.25) = 3 dark and round(1.3) = 1 bright."""
    lay, images = distinct_images()
    f = fit("trim", problem(images, lay), drop_dark=0.25, drop_bright=0.1, refine=0)
    kept = f.valid.sum(axis=0)
    assert (kept == 16 - 3 - 1).all()
    order = np.argsort(np.argsort(images, axis=0), axis=0)     # ranks 0..15
    assert (f.valid == ((order >= 3) & (order < 15))).all()


def test_six_lights_drop_one_from_each_end():
    """round(0.25 * 3) = 1: a rig of 6 lights still loses its darkest and brightest."""
    lay, images = distinct_images()
    valid = np.ones(images.shape, dtype=bool)
    valid[6:] = False
    f = fit("trim", problem(images, lay, valid=valid), refine=0)
    assert (f.valid.sum(axis=0) == 4).all()
    order = np.argsort(np.argsort(np.where(valid, images, np.inf), axis=0), axis=0)
    assert (f.valid == (valid & (order >= 1) & (order < 5))).all()


def test_ties_with_a_dropped_value_go_with_it():
    """A run of zeros (shadow) is one level: all of it is dropped."""
    surf, lay, images = lambert_scene(16)
    images = images.copy()
    images[:6] = 0.0
    for refine in (0, 1):
        f = fit("trim", problem(images, lay, object_mask=surf.object_mask), refine=refine)
        assert not f.valid[:6].any() and f.valid[6:].sum(axis=0).min() >= 3


def test_ranks_among_valid_observations():
    lay, images = distinct_images()
    valid = np.ones(images.shape, dtype=bool)
    valid[:8] = False                                            # 8 valid left: drop 1 + 1
    f = fit("trim", problem(images, lay, valid=valid), refine=0)
    assert not f.valid[:8].any() and (f.valid.sum(axis=0) == 6).all()
    ranks = np.argsort(np.argsort(images[8:], axis=0), axis=0)
    assert (f.valid[8:] == ((ranks >= 1) & (ranks < 7))).all()
    valid[8:10] = False                                          # 6 valid, 0.4: drop 1 + 1
    f = fit("trim", problem(images, lay, valid=valid), drop_dark=0.4, drop_bright=0.4,
            refine=0)
    assert (f.valid.sum(axis=0) == 4).all()
    valid[10:12] = False                  # 4 valid: one redundant observation, none dropped
    f = fit("trim", problem(images, lay, valid=valid), drop_dark=0.4, drop_bright=0.4)
    assert (f.valid == valid).all()


def test_refine_drops_an_outlier_inside_the_order():
    """A dim observation tripled stays in the middle ranks: the intensity trimming
    keeps it, the residual-ranked pass swaps it for a consistent one (same count)."""
    lay, images = distinct_images()
    images = images.copy()
    dim = np.argsort(images, axis=0)[4]                          # 5th darkest per pixel
    np.put_along_axis(images, dim[None], 1.5 * np.take_along_axis(images, dim[None], 0), 0)
    hit = np.zeros(images.shape, dtype=bool)
    np.put_along_axis(hit, dim[None], True, 0)
    f0 = fit("trim", problem(images, lay), refine=0)
    f1 = fit("trim", problem(images, lay), refine=1)
    moved = (f0.valid & hit).any(axis=0)
    assert moved.mean() > 0.5                                    # mostly kept by ranks
    assert not (f1.valid & hit).any()
    assert (f1.valid.sum(axis=0) == f0.valid.sum(axis=0)).all()


def test_few_lights_keep_redundancy():
    """With 8 lights the default drops 1 + 1 (of m - 3 = 5), never down to 4."""
    lay = ps.layout("12x4+32x4")
    rng = np.random.default_rng(1)
    n = rng.normal(size=(8, 8, 3)) * [0.2, 0.2, 1.0]
    n[..., 2] = np.abs(n[..., 2]) + 1.0
    images = np.einsum("kc,hwc->khw", lay.S, n).astype(np.float32)
    images += rng.normal(0, 0.01, images.shape).astype(np.float32)   # distinct residuals
    f = fit("trim", problem(images, lay))
    assert (f.valid.sum(axis=0) == 6).all()


@pytest.mark.parametrize("refine", [-1, 1.5, True])
def test_refine_is_a_count(refine):
    with pytest.raises(PsbenchError, match="refine"):
        TrimOptions(refine=refine)


@pytest.mark.parametrize("kw", [{"drop_dark": 0.5}, {"drop_dark": -0.01},
                                {"drop_bright": 0.7}, {"drop_bright": "a"}])
def test_fractions_in_range(kw):
    with pytest.raises(PsbenchError, match=rf"{next(iter(kw))} must be a number in \[0, 0.5\)"):
        TrimOptions(**kw)
