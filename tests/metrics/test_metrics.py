"""Tests for psbench.metrics: NE (Eq. 2.28), IE (Eqs. 2.29-2.31), QF (Eq. 2.32)."""
from types import SimpleNamespace

import numpy as np
import pytest

from psbench._shared.checks import PsbenchError
from psbench import metrics as M


def _rand_normals(H=12, W=10, seed=0):
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(H, W, 3))
    n[..., 2] = np.abs(n[..., 2]) + 0.3
    return (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)


def _rotate_x(n, deg):
    """Tilt every normal by ``deg`` about an axis perpendicular to it (in float64)."""
    n = n.astype(np.float64)
    t = np.cross(n, [1.0, 0.0, 0.0])
    t /= np.linalg.norm(t, axis=-1, keepdims=True)
    a = np.radians(deg)
    return np.cos(a) * n + np.sin(a) * t


def _S(k=6, zenith=45.0):
    pol = np.radians(np.arange(k) * 360.0 / k)
    z = np.radians(zenith)
    return np.stack([np.sin(z) * np.cos(pol), np.sin(z) * np.sin(pol),
                     np.full(k, np.cos(z))], axis=1)


# ------------------------------------------------------------------ NE
def test_ne_identical_is_zero():
    n = _rand_normals()
    assert M.normal_error(n, n) == pytest.approx(0.0, abs=1e-4)
    assert np.all(M.normal_error_map(n, n) < 1e-4)


@pytest.mark.parametrize("deg", [0.01, 1.0, 10.0, 90.0, 170.0])
def test_ne_known_rotation(deg):
    n = _rand_normals().astype(np.float64)
    r = _rotate_x(n, deg)
    e = M.normal_error_map(r, n)
    np.testing.assert_allclose(e, deg, rtol=1e-6, atol=1e-9)
    assert M.normal_error(r, n) == pytest.approx(deg, rel=1e-6)


def test_ne_scale_invariant_and_masked():
    n = _rand_normals().astype(np.float64)
    r = _rotate_x(n, 10.0)
    r[:, :5] = n[:, :5] * 3.0  # parallel, longer: 0 degrees
    m = np.zeros(n.shape[:2], bool)
    m[:, 5:] = True
    assert M.normal_error(r, n, object_mask=m) == pytest.approx(10.0, rel=1e-6)
    assert M.normal_error(r, n) == pytest.approx(5.0, rel=1e-6)
    assert np.isnan(M.normal_error(r, n, object_mask=np.zeros_like(m)))


def test_ne_stats_fractions():
    H, W = 4, 5
    truth = np.zeros((H, W, 3))
    truth[..., 2] = 1
    angles = np.array([0, 1, 4.9, 5, 7, 9.99, 10, 15, 19.9, 20,
                       25, 30, 40, 50, 60, 70, 80, 85, 89, 2.0]).reshape(H, W)
    a = np.radians(angles)
    est = np.dstack([np.sin(a), np.zeros_like(a), np.cos(a)])
    s = M.normal_error_stats(est, truth)
    assert s["lt5"] == pytest.approx(4 / 20)    # 0, 1, 4.9, 2
    assert s["lt10"] == pytest.approx(7 / 20)   # + 5, 7, 9.99
    assert s["lt20"] == pytest.approx(10 / 20)  # + 10, 15, 19.9
    assert s["mean"] == pytest.approx(angles.mean(), rel=1e-9)
    assert s["median"] == pytest.approx(np.median(angles), rel=1e-9)
    m = angles < 12
    s2 = M.normal_error_stats(est, truth, object_mask=m)
    assert s2["lt20"] == 1.0 and s2["lt5"] == pytest.approx(4 / m.sum())


def test_ne_by_zenith_bins():
    # truth zenith 5 deg on the left half, 50 on the right; error 2 and 8 deg
    H, W = 6, 8
    zen = np.where(np.arange(W) < 4, 5.0, 50.0)[None, :] * np.ones((H, 1))
    z = np.radians(zen)
    truth = np.dstack([np.sin(z), np.zeros_like(z), np.cos(z)])
    err = np.where(np.arange(W) < 4, 2.0, 8.0)[None, :] * np.ones((H, 1))
    e = np.radians(zen + err)
    est = np.dstack([np.sin(e), np.zeros_like(e), np.cos(e)])
    df = M.ne_by_zenith(est, truth, bins=[0, 10, 45, 90])
    assert list(df.columns[:5]) == ["zenith", "lo", "hi", "ne", "count"]
    assert df["count"].tolist() == [24, 0, 24]
    assert df["ne"][0] == pytest.approx(2.0) and df["ne"][2] == pytest.approx(8.0)
    assert np.isnan(df["ne"][1])
    assert df["zenith"].tolist() == [5.0, 27.5, 67.5]
    m = np.zeros((H, W), bool)
    m[:, :2] = True
    assert M.ne_by_zenith(est, truth, object_mask=m, bins=3)["count"].sum() == 12


@pytest.mark.parametrize("a, b, msg", [
    (np.zeros((4, 4, 2)), np.zeros((4, 4, 3)), "normals must have shape"),
    (np.zeros((4, 4, 3)), np.zeros((4, 5, 3)), "truth must have shape"),
    (np.full((4, 4, 3), np.nan), np.zeros((4, 4, 3)), "NaN"),
])
def test_ne_bad_shapes(a, b, msg):
    with pytest.raises(PsbenchError, match=msg):
        M.normal_error(a, b)


def test_ne_bad_mask():
    n = _rand_normals()
    with pytest.raises(PsbenchError, match="mask must have shape"):
        M.normal_error(n, n, object_mask=np.ones((3, 3), bool))


# ------------------------------------------------------------------ IE
def _lambert_case(k=6, H=7, W=9, seed=0):
    rng = np.random.default_rng(seed)
    n = _rand_normals(H, W, seed)
    rho = rng.uniform(0.3, 1.0, size=(H, W)).astype(np.float32)
    S = _S(k)
    b = n * rho[..., None]
    images = np.einsum("kc,hwc->khw", S, b).astype(np.float32)  # linear, may be < 0
    return images, n, rho, S, b


def test_ie_zero_for_exact_lambert():
    images, n, rho, S, b = _lambert_case()
    res = SimpleNamespace(normals=n, albedo=rho, lights=S)
    for norm in M.NORMS:
        assert M.intensity_error(images, res, norm=norm) == pytest.approx(0.0, abs=1e-6)
        assert M.intensity_error(images, b, S, norm=norm) == pytest.approx(0.0, abs=1e-6)


def test_ie_planted_residual():
    images, n, rho, S, b = _lambert_case(k=4)
    planted = np.zeros_like(images)
    planted[:, 2, 3] = [0.1, -0.2, 0.0, 0.4]  # one pixel, 4 images
    imgs = images + planted
    H, W = images.shape[1:]
    res = SimpleNamespace(normals=n, albedo=rho, lights=S)
    l1 = M.intensity_error(imgs, res, norm="l1", per_pixel=True)
    l2 = M.intensity_error(imgs, res, norm="l2", per_pixel=True)
    li = M.intensity_error(imgs, res, norm="linf", per_pixel=True)
    assert l1[2, 3] == pytest.approx(0.7 / 4, rel=1e-4)                 # mean |R|
    assert l2[2, 3] == pytest.approx(np.sqrt(0.21 / 4), rel=1e-4)       # RMS
    assert li[2, 3] == pytest.approx(0.4, rel=1e-4)                     # max |R|
    l1[2, 3] = l2[2, 3] = li[2, 3] = 0
    assert max(l1.max(), l2.max(), li.max()) < 1e-5
    # mean over pixels and over a mask
    assert M.intensity_error(imgs, res, norm="l1") == pytest.approx(0.7 / 4 / (H * W), rel=1e-3)
    m = np.zeros((H, W), bool)
    m[2, 3] = m[0, 0] = True
    assert M.intensity_error(imgs, res, norm="linf", object_mask=m) == pytest.approx(0.2, rel=1e-4)
    # plain vector norms of Eq. 2.31's text
    raw = M.intensity_error(imgs, res, norm="l2", per_pixel=True, average=False)
    assert raw[2, 3] == pytest.approx(np.sqrt(0.21), rel=1e-4)
    assert M.intensity_error(imgs, res, norm="l1", per_pixel=True,
                             average=False)[2, 3] == pytest.approx(0.7, rel=1e-4)
    # explicit lights override result.lights
    res2 = SimpleNamespace(normals=n, albedo=rho, lights=S * 2)
    assert M.intensity_error(imgs, res2, S, norm="linf", object_mask=m) == pytest.approx(0.2, rel=1e-4)


def test_ie_clamp_and_valid():
    images, n, rho, S, b = _lambert_case(k=6, seed=3)
    neg = images < 0
    assert neg.any()
    shaded = np.maximum(images, 0)  # attached shadows clamp the image
    res = SimpleNamespace(normals=n, albedo=rho, lights=S)
    assert M.intensity_error(shaded, res, clamp=True) == pytest.approx(0.0, abs=1e-6)
    assert M.intensity_error(shaded, res, clamp=False) > 1e-3
    # excluding the shadowed observations recovers 0 with the linear model
    assert M.intensity_error(shaded, res, valid=~neg) == pytest.approx(0.0, abs=1e-6)


def test_ie_lambert_matches_ls_residual():
    # with b = S^+ I the residual is (1 - S S^+) I  (Eq. 2.31)
    rng = np.random.default_rng(2)
    S = _S(8)
    images = rng.uniform(0, 1, size=(8, 5, 6)).astype(np.float32)
    b = np.einsum("ck,khw->hwc", np.linalg.pinv(S), images)
    R = images - np.einsum("kc,hwc->khw", S, b)
    want = np.sqrt((R ** 2).mean(axis=0))
    got = M.intensity_error(images, b, S, per_pixel=True)
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-6)


def test_weighted_ie():
    H, W = 3, 4
    ie1 = np.full((H, W), 2.0)
    ie2 = np.full((H, W), 6.0)
    w1 = np.full((H, W), 0.25)
    w = np.stack([w1, 1 - w1])
    assert M.weighted_intensity_error(np.stack([ie1, ie2]), w) == pytest.approx(5.0)
    m = np.zeros((H, W), bool)
    m[0, 0] = True
    w[0, 0, 0] = 1.0  # all weight on ring 0 at (0, 0)
    w[1, 0, 0] = 0.0
    assert M.weighted_intensity_error(np.stack([ie1, ie2]), w, object_mask=m) == pytest.approx(2.0)
    with pytest.raises(PsbenchError, match="weights must have shape"):
        M.weighted_intensity_error(np.stack([ie1, ie2]), w[:1])


def test_ie_with_ring_weights():
    images, n, rho, S, b = _lambert_case(k=8)
    planted = np.zeros_like(images)
    planted[:4] = 0.1  # ring 0 images off by 0.1 everywhere
    lights = SimpleNamespace(S=S, rings=lambda: [np.arange(4), np.arange(4, 8)])
    res = SimpleNamespace(normals=n, albedo=rho, lights=lights)
    H, W = images.shape[1:]
    w = np.stack([np.full((H, W), 0.3), np.full((H, W), 0.7)])
    ie = M.intensity_error(images + planted, res, norm="l1", weights=w)
    assert ie == pytest.approx(0.3 * 0.1, rel=1e-4)
    with pytest.raises(PsbenchError, match="weights must have shape"):
        M.intensity_error(images, res, weights=w[:1])
    with pytest.raises(PsbenchError, match="Layout"):
        M.intensity_error(images, b, S, weights=w)


def test_ie_relative():
    images, n, rho, S, b = _lambert_case(k=4)
    imgs = images + 0.05
    res = SimpleNamespace(normals=n, albedo=rho, lights=S)
    dr = np.mean([im.max() - im.min() for im in images])
    assert M.ie_relative(imgs, res, norm="l1") == pytest.approx(100 * 0.05 / dr, rel=1e-4)
    assert M.dynamic_range(imgs) == pytest.approx(dr, rel=1e-5)
    assert M.ie_relative(imgs, res, norm="l1", dynamic_range=[0.5, 1.5]) == pytest.approx(5.0)
    pp = M.ie_relative(imgs, res, norm="l1", dynamic_range=0.5, per_pixel=True)
    np.testing.assert_allclose(pp, 10.0, rtol=1e-4)
    assert np.isnan(M.ie_relative(imgs, res, dynamic_range=0.0))


@pytest.mark.parametrize("kw, msg", [
    (dict(images=np.zeros((4, 5)), result=np.zeros((4, 5, 3)), lights=np.eye(3)[:1]),
     "images must have shape"),
    (dict(images=np.zeros((3, 4, 5)), result=np.zeros((4, 6, 3)), lights=np.eye(3)),
     "result must have shape"),
    (dict(images=np.zeros((3, 4, 5)), result=np.zeros((4, 5, 3)), lights=np.eye(4)[:, :3]),
     "lights has 4 lights"),
    (dict(images=np.zeros((3, 4, 5)), result=np.zeros((4, 5, 3)), lights=None),
     "lights are required"),
    (dict(images=np.zeros((3, 4, 5)), result=np.zeros((4, 5, 3)), lights=np.eye(3),
          norm="l3"), "norm"),
    (dict(images=np.zeros((3, 4, 5)), result=np.zeros((4, 5, 3)), lights=np.eye(3),
          valid=np.ones((3, 4), bool)), "valid must have shape"),
    (dict(images=np.zeros((3, 4, 5)), result=np.zeros((4, 5, 3)), lights=np.eye(3),
          object_mask=np.ones((5, 4), bool)), "object_mask must have shape"),
    (dict(images=np.zeros((3, 4, 5)), result=SimpleNamespace(normals=np.zeros((4, 5, 3))),
          lights=np.eye(3)), "albedo"),
])
def test_ie_bad_input(kw, msg):
    with pytest.raises(PsbenchError, match=msg):
        M.intensity_error(**kw)


# ------------------------------------------------------------------ QF
def _qf_case():
    # k=2 images, 1x6 pixels; hand-made truth and flags
    hi = np.array([[[1, 1, 0, 0, 0, 0]], [[0, 0, 0, 0, 0, 0]]], bool)
    ss = np.array([[[0, 0, 0, 0, 0, 0]], [[1, 0, 0, 0, 0, 0]]], bool)
    cs = np.array([[[0, 0, 1, 0, 0, 0]], [[0, 1, 0, 0, 0, 0]]], bool)
    fl = np.array([[[1, 0, 1, 1, 0, 0]], [[0, 1, 0, 1, 1, 0]]], bool)
    return fl, dict(highlight=hi, self_shadow=ss, cast_shadow=cs)


def test_qf_hand_computed():
    fl, truth = _qf_case()
    # positives: hi {(0,0),(0,1)}, sh {(1,0),(0,2),(1,1)}
    # flagged: (0,0) hi TP, (0,2) sh TP, (0,3) FP, (1,1) sh TP, (1,3) FP, (1,4) FP
    # hi: TP 1, FN 1 [(0,1)], FP 3 -> 1/5
    # sh: TP 2, FN 1 [(1,0)], FP 3 -> 2/6
    # total: TP 3, FN 2, FP 3 -> 3/8
    q = M.quality_factor(fl, truth)
    assert q == pytest.approx(dict(hi=1 / 5, sh=2 / 6, total=3 / 8))
    c = M.quality_counts(fl, truth)
    assert c["total"] == dict(tp=3, fp=3, fn=2)
    # a Scene-like object works the same
    scene = SimpleNamespace(**truth)
    assert M.quality_factor(fl, scene) == q


def test_qf_mask_and_perfect():
    fl, truth = _qf_case()
    m = np.array([[1, 1, 1, 0, 0, 1]], bool)  # drop the false-alarm columns 3, 4
    q = M.quality_factor(fl, truth, object_mask=m)
    # hi: TP 1, FN 1, FP 0 -> 1/2; sh: TP 2, FN 1 -> 2/3; total: 3/5
    assert q == pytest.approx(dict(hi=1 / 2, sh=2 / 3, total=3 / 5))
    pos = truth["highlight"] | truth["self_shadow"] | truth["cast_shadow"]
    assert M.quality_factor(pos, truth) == dict(hi=1.0, sh=1.0, total=1.0)


def test_qf_empty_class_is_nan():
    k, H, W = 3, 4, 4
    z = np.zeros((k, H, W), bool)
    hi = z.copy()
    hi[0, 1, 1] = True
    truth = dict(highlight=hi, self_shadow=z, cast_shadow=z)
    q = M.quality_factor(hi.copy(), truth)
    assert q["hi"] == 1.0 and q["total"] == 1.0 and np.isnan(q["sh"])
    # nothing flagged, no positives at all: N/A everywhere
    q0 = M.quality_factor(z, dict(highlight=z, self_shadow=z, cast_shadow=z))
    assert all(np.isnan(v) for v in q0.values())
    # a false alarm makes an empty class 0, not N/A
    f = z.copy()
    f[2, 0, 0] = True
    assert M.quality_factor(f, truth)["sh"] == 0.0
    # nothing flagged with positives present: 0
    assert M.quality_factor(z, truth)["hi"] == 0.0


def test_qf_targets_report_na():
    fl, truth = _qf_case()
    q = M.quality_factor(fl, truth, targets=("hi",))  # e.g. the Re mask
    assert q["hi"] == pytest.approx(1 / 5) and np.isnan(q["sh"])
    assert q["total"] == pytest.approx(3 / 8)
    assert M.quality_factor(fl, truth, targets="sh")["sh"] == pytest.approx(2 / 6)
    assert all(np.isnan(v) for v in M.quality_factor(fl, truth, targets=()).values())
    with pytest.raises(PsbenchError, match="targets"):
        M.quality_factor(fl, truth, targets=("hi", "cs"))


def test_qf_bad_input():
    fl, truth = _qf_case()
    with pytest.raises(PsbenchError, match="flagged must have shape"):
        M.quality_factor(fl[0], truth)
    with pytest.raises(PsbenchError, match="flagged must be a bool"):
        M.quality_factor(fl.astype(int), truth)
    with pytest.raises(PsbenchError, match="truth.highlight must have shape"):
        M.quality_factor(fl, dict(truth, highlight=truth["highlight"][:1]))
    with pytest.raises(PsbenchError, match="highlight"):
        M.quality_factor(fl, dict(self_shadow=truth["self_shadow"]))
    with pytest.raises(PsbenchError, match="mask must have shape"):
        M.quality_factor(fl, truth, object_mask=np.ones((2, 2), bool))


# ------------------------------------------------------------------ with rendered scenes
def test_metrics_on_rendered_scene():
    import psbench as ps

    surf = ps.make_surface("semisphere_disc", size=64)
    lay = ps.layout("45x8")
    sc = ps.render(surf, lay, model="lambert", shadows=True)
    b = surf.normals.astype(np.float64)  # albedo 1
    # attached shadows clamp the images: the clamped prediction is exact,
    # the linear one is not unless shadowed observations are left out
    assert M.intensity_error(sc.images, b, lay, object_mask=surf.object_mask, clamp=True) < 1e-5
    assert M.intensity_error(sc.images, b, lay, object_mask=surf.object_mask) > 1e-3
    assert M.intensity_error(sc.images, b, lay, object_mask=surf.object_mask, valid=~sc.shadow) < 1e-5
    # QF with the Scene itself as truth: flagging exactly the truth is perfect
    sc2 = ps.render(surf, lay, model="ts")
    q = M.quality_factor(sc2.highlight | sc2.shadow, sc2, object_mask=surf.object_mask)
    assert q == dict(hi=1.0, sh=1.0, total=1.0)
    assert M.normal_error(surf.normals, surf.normals, object_mask=surf.object_mask) == pytest.approx(0, abs=1e-3)
