"""Public API of psbench.solve: Result, validation, thresholds, degenerate input,
method delegation."""
import warnings

import numpy as np
import pytest

import psbench as ps
from psbench._shared.checks import PsbenchError
from psbench.solve import MASKS, Result, solve
from psbench.solve.thresholds import resolve_thresholds, t_re, polar_spacing


@pytest.fixture(scope="module")
def scene():
    surf = ps.make_surface("sombrero", size=48)
    lay = ps.layout("45x8")
    return surf, lay, ps.render(surf, lay)


def test_result_fields(scene):
    surf, lay, sc = scene
    res = solve(sc.images, lay, mask="Th-Hi-Re-Sh", object_mask=surf.object_mask, want_height=True)
    assert isinstance(res, Result)
    k, H, W = sc.images.shape
    assert res.normals.shape == (H, W, 3) and res.normals.dtype == np.float32
    assert res.albedo.shape == (H, W)
    assert res.valid.shape == (k, H, W) and res.valid.dtype == bool
    assert res.weights is None
    assert res.residual.shape == (H, W) and res.residual.dtype == np.float32
    assert res.height.shape == (H, W)
    assert "total" in res.timings and res.timings["total"] >= 0
    assert res.lights is lay and res.mask == "Th-Hi-Re-Sh" and res.method == "ps"
    assert set(res.thresholds) >= {"k_low", "k_up", "k_Hi", "k_CS", "t_NL", "t_Re"}
    assert res.thresholds["t_Re"] == 22.5
    for a in (res.normals, res.albedo, res.residual, res.height):
        assert np.isfinite(a).all()
    out = ~surf.object_mask
    assert np.allclose(res.normals[out], (0, 0, 1)) and (res.albedo[out] == 0).all()
    assert res.valid[:, out].all()
    assert np.allclose(np.linalg.norm(res.normals, axis=-1), 1, atol=1e-5)


def test_residual_is_l2_over_used_observations(scene):
    surf, lay, sc = scene
    res = solve(sc.images, lay, mask="Th")
    L = np.einsum("kc,hwc->khw", lay.S, res.normals * res.albedo[..., None])
    want = np.sqrt((((sc.images - L) ** 2) * res.valid).sum(0))
    assert np.allclose(res.residual, want, atol=1e-4)
    none = solve(sc.images, lay)
    want = np.sqrt(((sc.images - np.einsum("kc,hwc->khw", lay.S, none.b)) ** 2).sum(0))
    assert np.allclose(none.residual, want, atol=1e-4)


def test_mask_names_and_canonical_form(scene):
    surf, lay, sc = scene
    a = solve(sc.images, lay, mask="th-hi")
    b = solve(sc.images, lay, mask="Th Hi")
    assert a.mask == b.mask == "Th-Hi"
    assert np.array_equal(a.valid, b.valid)
    assert solve(sc.images, lay, mask=None).mask == "None"
    assert set(MASKS) == {"None", "Th", "NL", "xNL", "SS", "Re", "CS", "Hi", "Sh", "CJ", "RA", "SR"}


def test_combination_is_and_of_image_masks(scene):
    surf, lay, sc = scene
    th = solve(sc.images, lay, mask="Th", max_iter=0)
    xnl = solve(sc.images, lay, mask="xNL", max_iter=0)
    both = solve(sc.images, lay, mask="xNL-Th", max_iter=0)
    # wherever AND leaves >= 3 observations the combination is exactly the AND
    inter = th.valid & xnl.valid
    ok = inter.sum(0) >= 3
    assert np.array_equal(both.valid[:, ok], inter[:, ok])


def test_layout_forms(scene):
    surf, lay, sc = scene
    r1 = solve(sc.images, "45x8")
    r2 = solve(sc.images, lay.directions)
    r3 = solve(sc.images, lay)
    assert np.allclose(r1.normals, r3.normals) and np.allclose(r2.normals, r3.normals)


def test_uint_images_converted():
    lay = ps.layout("45x4")
    img = (np.random.default_rng(0).random((4, 8, 8)) * 255).astype(np.uint8)
    res = solve(img, lay)
    want = solve(img.astype(np.float32) / 255, lay)
    assert np.allclose(res.normals, want.normals, atol=1e-6)


def test_albedo_zero_gives_up_normal():
    lay = ps.layout("45x8")
    img = np.zeros((8, 6, 6), np.float32)
    img[:, 3:] = (lay.S @ np.array([0.2, 0.1, 0.97]))[:, None, None]
    res = solve(img, lay, mask="Th-Hi")
    assert np.allclose(res.normals[:3], (0, 0, 1))
    assert (res.albedo[:3] == 0).all()
    assert np.allclose(res.normals[3:], np.array([0.2, 0.1, 0.97]) / np.linalg.norm([0.2, 0.1, 0.97]),
                       atol=1e-5)


def test_all_zero_images_warn():
    lay = ps.layout("45x8")
    with pytest.warns(RuntimeWarning, match="zero"):
        res = solve(np.zeros((8, 5, 5), np.float32), lay, mask="Th-Hi-Re-Sh", weighted=True)
    assert np.allclose(res.normals, (0, 0, 1)) and (res.albedo == 0).all()
    assert np.isfinite(res.residual).all()
    with pytest.warns(RuntimeWarning, match="zero"):
        solve(np.zeros((8, 5, 5), np.float32), lay)


def test_constant_images_are_a_plane():
    lay = ps.layout("45x8")
    img = np.full((8, 5, 5), 0.5, np.float32)
    with pytest.warns(RuntimeWarning, match="dynamic range"):
        res = solve(img, lay, mask="Th-Hi-CS")
    assert np.allclose(res.normals, (0, 0, 1), atol=1e-5)
    assert np.allclose(res.albedo, 0.5 / np.cos(np.radians(45)), atol=1e-5)
    assert res.valid.all()


# ------------------------------------------------------------------- errors
@pytest.mark.parametrize("kwargs, match", [
    (dict(images=np.zeros((2, 4, 4))), "at least 3"),
    (dict(images=np.zeros((4, 4))), r"\(k, H, W\)"),
    (dict(images=np.full((8, 4, 4), np.nan)), "NaN"),
    (dict(lights="45x4"), r"4 lights.*8 images"),
    (dict(lights=np.ones((8, 2))), "lights"),
    (dict(lights="banana"), "lights"),
    (dict(object_mask=np.ones((3, 3), bool)), "object_mask"),
    (dict(object_mask=np.zeros((6, 6), bool)), "no pixel"),
    (dict(mask="Th-Foo"), "valid masks: None, Th, NL, xNL, SS, Re, CS, Hi, Sh, CJ, RA"),
    (dict(mask=3), "mask"),
    (dict(mask="NL"), "exactly 4"),
    (dict(mask="CJ"), "exactly 4"),
    (dict(thresholds={"k_lo": 0.1}), "unknown name 'k_lo'"),
    (dict(thresholds={"k_low": 1.5}), "out of range"),
    (dict(thresholds={"k_low": 0.5, "k_up": 0.4}), "below k_up"),
    (dict(thresholds={"t_Re": -1}), "out of range"),
    (dict(thresholds={"t_NL": "x"}), "t_NL"),
    (dict(thresholds=[1]), "dict"),
    (dict(method="magic"), "method"),
    (dict(th_scope="galaxy"), "th_scope"),
    (dict(max_iter=-1), "max_iter"),
    (dict(truth_normals=np.zeros((3, 3, 3))), "truth_normals"),
    (dict(dilate_radius=-2), "dilate_radius"),
    (dict(kernel_size=14), "kernel_size"),
    (dict(banana=1), "unknown option"),
    (dict(images=np.ones((8, 1, 6)), mask="Th-Sh"), "2x2"),
])
def test_bad_input(kwargs, match):
    args = dict(images=np.random.default_rng(0).random((8, 6, 6)).astype(np.float32),
                lights="45x8")
    args.update(kwargs)
    with pytest.raises(PsbenchError, match=match):
        solve(args.pop("images"), args.pop("lights"), **args)


def test_cj_cannot_combine():
    img = np.random.default_rng(0).random((4, 6, 6)).astype(np.float32)
    with pytest.raises(PsbenchError, match="CJ"):
        solve(img, "45x4", mask="CJ-Th")


# ------------------------------------------------------------------- thresholds
def test_table_5_2_columns():
    for k, want in {4: (0.02, 0.35, 0.03, -0.1, 0.02), 6: (0.06, 0.35, 0.04, -0.1, 0.04),
                    8: (0.06, 0.35, 0.05, -0.1, 0.02), 12: (0.08, 0.35, 0.06, -0.1, 0.01)}.items():
        t = resolve_thresholds(k)
        assert (t["k_low"], t["k_up"], t["k_Hi"], t["k_CS"], t["t_NL"]) == pytest.approx(want)


def test_thresholds_interpolate_and_clamp():
    assert resolve_thresholds(5)["k_low"] == pytest.approx(0.04)
    assert resolve_thresholds(10)["k_Hi"] == pytest.approx(0.055)
    assert resolve_thresholds(3)["k_low"] == pytest.approx(0.02)
    assert resolve_thresholds(16)["t_NL"] == pytest.approx(0.01)


def test_t_re_eq_5_1():
    assert t_re(ps.layout("45x8")) == pytest.approx([22.5] * 8)
    assert t_re(ps.layout("30x4")) == pytest.approx([30.0] * 4)   # min(30, 30, 90)
    assert t_re(ps.layout("15x8")) == pytest.approx([15.0] * 8)
    assert t_re(ps.layout("45x16")) == pytest.approx([22.5] * 16)
    assert polar_spacing(ps.layout("30x8+60x8")) == pytest.approx(22.5)
    two = t_re(ps.layout("30x8+60x8"))
    assert two[:8] == pytest.approx([22.5] * 8) and two[8:] == pytest.approx([15.0] * 8)
    res = resolve_thresholds(16, ps.layout("30x8+60x8"))
    assert isinstance(res["t_Re"], tuple) and len(res["t_Re"]) == 16


def test_threshold_overrides_used(scene):
    surf, lay, sc = scene
    a = solve(sc.images, lay, mask="Th", thresholds={"k_low": 0.2})
    b = solve(sc.images, lay, mask="Th")
    assert a.thresholds["k_low"] == 0.2 and b.thresholds["k_low"] == 0.06
    assert (~a.valid).sum() > (~b.valid).sum()
    c = solve(sc.images, lay, mask="Re", thresholds={"t_Re": [10.0] * 8})
    assert c.thresholds["t_Re"] == 10.0


# ------------------------------------------------------------------- methods
def test_wps_is_delegated(scene):
    """solve(method="wps") hands its keywords to the registered "wps" method (replaced
    here by a stand-in with the same options class)."""
    from psbench import registry
    from psbench.solve.base import Fit
    surf, lay, sc = scene
    real = registry.get("methods", "wps")
    seen = {}

    def fake(problem, options):
        seen.update(problem=problem, options=options)
        return Fit(b=np.zeros(problem.images.shape[1:] + (3,), np.float32), info={"fake": 1})

    registry.register("methods", registry.Method("wps", fake, options=real.options,
                                                 masked=False), replace=True)
    try:
        out = solve(sc.images, lay, method="wps", weight="eZsource", binary=True, seed=3)
    finally:
        registry.register("methods", real, replace=True)
    assert registry.get("methods", "wps") is real
    assert out.info["fake"] == 1 and out.method == "wps"
    o, pr = seen["options"], seen["problem"]
    assert o.weight == "eZsource" and o.binary is True and pr.seed == 3
    assert pr.lights is lay and pr.images.dtype == np.float32


def test_weighted_options(scene):
    surf, lay, sc = scene
    a = solve(sc.images, lay, mask="Th", weighted=True)
    b = solve(sc.images, lay, mask="Th", weighted=True, dilate_radius=2, kernel_size=5,
              smooth_sigma=1.0, sigma_min=0.05)
    assert a.weights.shape == sc.images.shape and (a.weights > 0).all()
    assert not np.allclose(a.weights, b.weights)
    assert "weights" in a.timings and "weighted_ps" in a.timings


def test_cj_result_valid():
    lay = ps.layout("45x4")
    n = np.array([0.1, 0.2, 0.97]) / np.linalg.norm([0.1, 0.2, 0.97])
    img = np.broadcast_to((lay.S @ n)[:, None, None], (4, 4, 4)).astype(np.float32).copy()
    img[2, 2:, 2:] += 0.8
    res = solve(img, lay, mask="CJ")
    assert res.valid[:, 0, 0].all()
    assert np.flatnonzero(~res.valid[:, 3, 3]).tolist() == [2]
    assert np.allclose(res.normals[3, 3], n, atol=1e-4)


def test_unmasked_residual_is_lazy_but_exact():
    import psbench as ps

    surf = ps.make_surface("sombrero2", size=48)
    lay = ps.layout("30x4+60x4")
    sc = ps.render(surf, lay, noise=0.05, seed=1)
    res = ps.solve(sc.images, lay, mask="None", object_mask=surf.object_mask)
    assert "residual" not in res.timings  # not computed during the solve
    want = np.sqrt(((sc.images - np.einsum("kc,hwc->khw", lay.S, res.b)) ** 2).sum(0))
    np.testing.assert_allclose(res.residual, want, rtol=1e-4, atol=1e-5)
    assert res.residual is res.residual  # computed once, then kept
