"""Ground-truth-free validation error (psbench.solve.validation, Result.ve)."""
import warnings

import numpy as np
import pytest

import psbench as ps
from psbench.solve.validation import lambert_heldout, validate


@pytest.fixture(scope="module")
def scene():
    surf = ps.make_surface("sombrero", size=40)
    lay = ps.layout("30x8+60x8")
    return surf, lay, ps.render(surf, lay, model="lambert", noise=0.0, shadows=False)


def test_heldout_equals_explicit_refit():
    rng = np.random.default_rng(0)
    S = ps.layout("45x8").S
    I = rng.uniform(0.2, 1.0, (8, 5)).astype(np.float32)
    w = np.ones((8, 5), bool)
    w[2, 1] = False
    e = lambert_heldout(I, S, w)
    for p in range(5):
        for i in range(8):
            keep = w[:, p].copy()
            if keep[i]:
                keep[i] = False
            b = np.linalg.lstsq(S[keep], I[keep, p].astype(np.float64), rcond=None)[0]
            assert e[i, p] == pytest.approx(I[i, p] - S[i] @ b, abs=2e-5)


def test_ve_zero_on_noiseless_lambert(scene):
    surf, lay, sc = scene
    res = ps.solve(sc.images, lay, mask="SS", object_mask=surf.object_mask)
    ve = res.ve
    assert ve.defined > 0.99
    assert ve.median < 1e-5 and ve.mean < 1e-4
    assert np.isnan(ve.map[~surf.object_mask]).all()


def test_ve_flags_a_planted_outlier(scene):
    surf, lay, sc = scene
    images = sc.images.copy()
    r, c = np.argwhere(surf.object_mask)[len(np.argwhere(surf.object_mask)) // 2]
    lit = np.flatnonzero(images[:, r, c] > 0)
    images[lit[0], r, c] += 0.5 * images[:, r, c].max()
    ve = ps.solve(images, lay, mask="SS", object_mask=surf.object_mask).ve.map
    others = np.delete(ve[surf.object_mask], np.ravel_multi_index((r, c), ve.shape) - 0)
    assert ve[r, c] > 1e-2
    assert ve[r, c] > 100 * np.nanmax(np.where(np.arange(ve.size).reshape(ve.shape) == r * ve.shape[1] + c,
                                               np.nan, ve)[surf.object_mask])
    assert others.size  # the map covers the object


@pytest.mark.parametrize("mask", ["None", "Th", "SS", "Re", "Hi", "Sh", "Th-Hi-Re-Sh", "xNL", "RA"])
@pytest.mark.parametrize("method", ["ps", "trim"])
def test_ve_composes_with_masks(mask, method):
    surf = ps.make_surface("sombrero", size=32)
    lay = ps.layout("30x8+60x8")
    sc = ps.render(surf, lay, model="ts", noise=0.01, seed=1)
    res = ps.solve(sc.images, lay, mask=mask, method=method, object_mask=surf.object_mask)
    used = res.weights if res.weights is not None else res.valid
    ref = validate(sc.images, lay, used, object_mask=surf.object_mask)
    np.testing.assert_array_equal(res.ve.map, ref.map)
    assert np.isnan(res.ve.map[~surf.object_mask]).all()
    # defined where at least 4 observations were used, NaN where fewer
    cnt = (np.asarray(used) > 0).sum(axis=0)
    om = surf.object_mask
    assert np.isnan(res.ve.map[om & (cnt < 4)]).all()
    assert np.isfinite(res.ve.map[om & (cnt >= 4)]).mean() > 0.95
    assert np.isfinite(res.ve.mean)


def test_tsfit_and_robust_ve_of_their_model():
    surf = ps.make_surface("sombrero", size=32)
    lay = ps.layout("30x8+60x8")
    sc = ps.render(surf, lay, model="ts", noise=0.0)
    lam = ps.solve(sc.images, lay, object_mask=surf.object_mask).ve
    for method in ("tsfit", "robust"):
        ve = ps.solve(sc.images, lay, method=method, object_mask=surf.object_mask).ve
        assert ve.map.shape == surf.object_mask.shape
        assert ve.median < 0.1 * lam.median  # the fitted model explains the highlights


def test_validation_map_median_is_nanmedian_bit_for_bit():
    """The compiled median of |e| over the used, finite errors equals numpy's nanmedian
    of the same values exactly: odd and even counts, ties, NaN and inf, empty pixels."""
    from psbench.solve import _heldout_kernel as hk
    rng = np.random.default_rng(3)
    for trial in range(60):
        k, n = int(rng.integers(1, 100)), int(rng.integers(1, 600))
        e = rng.normal(size=(k, n)).astype(np.float32)
        if trial % 2:
            e = np.round(e, 1)          # many ties
        e[rng.random((k, n)) < 0.1] = np.nan
        e[rng.random((k, n)) < 0.02] = np.inf
        used = rng.random((k, n)) < rng.random()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            ref = np.nanmedian(np.where(used & np.isfinite(e), np.abs(e), np.nan), axis=0)
        out = np.empty(n, np.float32)
        hk.abs_median(e, used.view(np.uint8), out)
        np.testing.assert_array_equal(out, ref)


def test_fused_median_equals_the_separate_pass():
    """The median the held-out kernels compute in their pass is abs_median of their
    errors, bit for bit (Lambert and Torrance-Sparrow, float and bool weights)."""
    from psbench.solve import _heldout_kernel as hk
    from psbench.solve.methods.tsfit import _lm
    from psbench.solve.validation import ts_heldout
    rng = np.random.default_rng(5)
    k, n = 24, 700
    d = rng.normal(size=(k, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.3
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    I = rng.random((k, n)).astype(np.float32)
    nrm = rng.normal(size=(3, n))
    nrm[2] = np.abs(nrm[2]) + 0.5
    nrm = (nrm / np.linalg.norm(nrm, axis=0)).astype(np.float32)
    L = _lm.Lights(d, np.ones(k))
    for w in (rng.random((k, n)) < 0.7, (rng.random((k, n)) * (rng.random((k, n)) < 0.8))
              .astype(np.float32)):
        w[:, :5] = 0   # pixels without observations: NaN
        for e, med in (lambert_heldout(I, d, w, median=True),
                       ts_heldout(I, L.table, w, nrm, 0.5, 0.3, 4.0, median=True)):
            ref = np.empty(n, np.float32)
            hk.abs_median(e, (np.asarray(w) > 0).view(np.uint8), ref)
            np.testing.assert_array_equal(med, ref)
            assert np.isnan(med[:5]).all() and np.isfinite(med[5:]).all()
