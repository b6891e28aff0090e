"""The held-out fallback (psbench.solve.fallback, Result.fallback) of robust and tsfit."""
import warnings

import numpy as np
import pytest

import psbench as ps
from psbench.solve import fallback as fb
from psbench.solve.validation import validation_map


@pytest.fixture(scope="module")
def bounce():
    """A scene the Torrance-Sparrow model does not explain everywhere (a GGX lobe)."""
    surf = ps.make_surface("mozart", size=32)
    lay = ps.layout("30x8+60x8")
    return surf, lay, ps.render(surf, lay, model="ggx", roughness=0.1, f0=0.04, noise=0.02,
                                seed=0)


def _solve(sc, lay, om, method, mask="None", **kw):
    with warnings.catch_warnings():   # convergence warnings of a few pixels: not tested
        warnings.simplefilter("ignore")
        return ps.solve(sc.images, lay, method=method, mask=mask, object_mask=om, **kw)


def test_rule_keeps_only_a_better_prediction():
    k, n = 8, 4
    e_s = np.full((k, n), 1.0, np.float32)
    e_m = e_s.copy()
    e_m[:, 0] = 0.1                        # clearly better
    e_m[:, 2] = np.nan                     # undefined: costs c^2
    e_m[:, 3] = [0.1, 2.0] * 4             # better on half, worse on half: not clearly
    E = np.ones((k, n), bool)
    mean, se, cnt = fb.compare(e_m, e_s, E, 1.0)
    keep = fb.keep(mean, se, cnt)
    assert keep.tolist() == [True, False, False, False]   # pixel 1: a tie falls back
    assert mean[2] == pytest.approx(fb.C ** 2 - 1.0)
    # the margin is in standard errors: a larger Z keeps fewer pixels
    assert fb.keep(mean, se, cnt, z=0.0).sum() >= fb.keep(mean, se, cnt, z=3.0).sum()
    # too few evaluation observations: fall back
    E[fb.MIN_EVAL - 1:, 0] = False
    assert not fb.keep(*fb.compare(e_m, e_s, E, 1.0))[0]


def test_robust_falls_back_to_trim_exactly(bounce):
    surf, lay, sc = bounce
    om = surf.object_mask
    r = _solve(sc, lay, om, "robust")
    t = _solve(sc, lay, om, "trim")
    f = r.fallback
    assert f.shape == om.shape and f.dtype == bool and not f[~om].any()
    assert f.any(), "the scene should make some pixels fall back"
    np.testing.assert_array_equal(r.normals[f], t.normals[f])      # bit for bit
    np.testing.assert_array_equal(r.albedo[f], t.albedo[f])
    assert r.info["fallback_fraction"] == pytest.approx(f[om].mean())
    off = _solve(sc, lay, om, "robust", fallback=False)
    assert off.fallback is None
    # where it did not fall back, the answer is the in-sample choice's
    keep = om & ~f
    np.testing.assert_array_equal(r.normals[keep], off.normals[keep])


def test_tsfit_falls_back_to_its_start_exactly(bounce):
    surf, lay, sc = bounce
    om = surf.object_mask
    t = _solve(sc, lay, om, "tsfit")
    start = _solve(sc, lay, om, "robust")
    f = t.fallback
    assert f.any() and not f.all() and not f[~om].any()
    np.testing.assert_array_equal(t.normals[f], start.normals[f])
    np.testing.assert_array_equal(t.albedo[f], start.albedo[f])
    # the fallen-back pixels carry the start's observations and validation error
    np.testing.assert_array_equal(t.weights[:, f] > 0, start.weights[:, f] > 0)
    np.testing.assert_array_equal(t.ve.map[f], start.ve.map[f])
    assert _solve(sc, lay, om, "tsfit", fallback=False).fallback is None


@pytest.mark.parametrize("mask", ["None", "Th", "SS", "Re", "Hi", "Sh", "Th-Hi-Re-Sh", "xNL",
                                  "RA", "Th-SS"])
@pytest.mark.parametrize("method", ["robust", "tsfit"])
def test_fallback_and_ve_compose_with_masks(bounce, mask, method):
    surf, lay, sc = bounce
    om = surf.object_mask
    res = _solve(sc, lay, om, method, mask=mask)
    f = res.fallback
    assert f.shape == om.shape and not f[~om].any()
    assert np.isnan(res.ve.map[~om]).all()
    used = (res.weights if res.weights is not None else res.valid) > 0
    # the validation error is that of the answer kept, over its used observations;
    # the fallen-back pixels hold the simpler fit's (defined where >= 4 were used)
    cnt = used.sum(axis=0)
    assert np.isnan(res.ve.map[om & (cnt < 4)]).all()
    assert np.isfinite(res.ve.map[om & (cnt >= 4)]).mean() > 0.95
    # the masks are respected: no observation a mask excluded is used
    plain = ps.solve(sc.images, lay, mask=mask, object_mask=om) if mask == "Th" \
        else None
    if plain is not None:
        assert not (used & ~plain.valid)[:, om].any()
        simpler = _solve(sc, lay, om, "trim" if method == "robust" else "robust", mask=mask)
        np.testing.assert_array_equal(res.normals[f], simpler.normals[f])


def test_ve_and_fallback_on_noiseless_lambert():
    surf = ps.make_surface("sombrero", size=32)
    lay = ps.layout("30x8+60x8")
    sc = ps.render(surf, lay, model="lambert", noise=0.0, shadows=False)
    om = surf.object_mask
    for method in ("robust", "tsfit"):
        res = _solve(sc, lay, om, method)
        assert res.ve.median < 1e-4, method
        # no fit predicts better than an exact one: nothing is gained by the richer model
        ne = np.degrees(np.arccos(np.clip((res.normals * surf.normals).sum(-1), -1, 1)))[om]
        assert ne.mean() < 0.05, method


def test_fallback_option_is_checked():
    surf = ps.make_surface("sombrero", size=16)
    lay = ps.layout("30x8+60x8")
    sc = ps.render(surf, lay, model="ts", noise=0.0)
    for method in ("robust", "tsfit"):
        with pytest.raises(ps.PsbenchError, match="fallback"):
            ps.solve(sc.images, lay, method=method, fallback="yes")


def test_validation_map_of_fallen_back_pixels_is_the_start_s(bounce):
    # the fallback reuses the start's held-out errors: ve recomputed from them agrees
    surf, lay, sc = bounce
    om = surf.object_mask
    r = _solve(sc, lay, om, "robust")
    t = _solve(sc, lay, om, "trim")
    f = r.fallback
    k = sc.images.shape[0]
    I = sc.images.reshape(k, -1)[:, f.reshape(-1)]
    from psbench.solve.validation import lambert_heldout
    w = t.valid.reshape(k, -1)[:, f.reshape(-1)]
    ref = validation_map(lambert_heldout(I, lay.S, w), w, I)
    np.testing.assert_allclose(r.ve.map[f], ref, rtol=1e-6)


def test_outputs_write_the_fallback_map(bounce, tmp_path):
    from psbench.io._write import write_outputs
    surf, lay, sc = bounce
    om = surf.object_mask
    r = _solve(sc, lay, om, "tsfit")
    files = write_outputs(tmp_path, r, object_mask=om, images=sc.images, height=False,
                          per_image=False)
    assert "fallback.png" in files and "fallback.npz" in files
    np.testing.assert_array_equal(np.load(tmp_path / "fallback.npz")["fallback"], r.fallback)


def test_paired_kernel_is_the_per_pixel_sums():
    """The compiled comparison equals the plain per-pixel sums over the lights in order
    (a Python loop doing the same float64 operations), over more than one block, with
    undefined errors and pixels of 0 and 1 evaluated observations."""
    from psbench.solve import _fallback_kernel as fk

    rng = np.random.default_rng(4)
    k, n = 7, fk.BLOCK + 900
    em = rng.normal(size=(k, n)).astype(np.float32)
    es = rng.normal(size=(k, n)).astype(np.float32)
    em[rng.random((k, n)) < 0.05] = np.nan
    E = (rng.random((k, n)) < 0.6).astype(np.uint8)
    E[:, :3] = 0
    E[0, 3:6] = 1
    E[1:, 3:6] = 0
    inv, c2 = rng.uniform(0.5, 3.0, k), 6.25
    mean, se, cnt = np.empty(n), np.empty(n), np.empty(n, np.int32)
    fk.paired(em, es, E, inv, c2, mean, se, cnt)
    for p in range(n):
        s = ss = 0.0
        c = 0
        for i in range(k):
            if E[i, p]:
                a, b = float(em[i, p]) * inv[i], float(es[i, p]) * inv[i]
                d = (min(a * a, c2) if a == a else c2) - (min(b * b, c2) if b == b else c2)
                s, ss, c = s + d, ss + d * d, c + 1
        assert cnt[p] == c
        if c == 0:
            assert mean[p] == 0.0 and se[p] == np.inf
            continue
        m = s / c
        assert mean[p] == m
        assert se[p] == (np.inf if c < 2 else np.sqrt(max(ss - c * m * m, 0.0) / (c - 1) / c))
