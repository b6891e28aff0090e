"""Masks of the unified PS on constructed cases with known answers, noiseless Lambert
scenes, weighted PS and FWLSE (psbench.solve)."""
import numpy as np
import pytest
from scipy import ndimage

import psbench as ps
from psbench.solve import kernel, solve
from psbench.solve._engine import _Completer
from psbench.solve.masks import ranges
from psbench.solve.masks.th import th as th_mask


def _dir(zen, pol):
    z, p = np.radians(zen), np.radians(pol)
    return np.array([np.sin(z) * np.cos(p), np.sin(z) * np.sin(p), np.cos(z)])


def _planted(k=12, zen=45, n=(0.1, 0.05, 1.0), hi=(), sh=(), hi_add=1.0, size=6, top=3.0,
             clamp=False):
    """k Lambert observations of one normal on a (size x size) patch, with a planted
    highlight (+hi_add) and a planted shadow (0) on the lower-right block; pixel (0, 0)
    is 0 and pixel (0, 1) is ``top`` in every image so each image's range is [0, top]."""
    lay = ps.layout(f"{zen}x{k}")
    n = np.asarray(n, float)
    n = n / np.linalg.norm(n)
    L = lay.S @ n
    if clamp:
        L = np.maximum(L, 0.0)
    img = np.broadcast_to(L[:, None, None], (k, size, size)).astype(np.float32).copy()
    for j in hi:
        img[j, 2:, 2:] += hi_add
    for j in sh:
        img[j, 2:, 2:] = 0.0
    img[:, 0, 0] = 0.0
    img[:, 0, 1] = top
    return img, lay, n, L


def _flags(res, px=(4, 4)):
    return sorted(np.flatnonzero(~res.valid[:, px[0], px[1]]).tolist())


def _angle(a, b):
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b))))


# ------------------------------------------------------------- constructed answers
@pytest.mark.parametrize("mask, kw, want", [
    ("Th", dict(hi=[1], sh=[4]), [1, 4]),
    ("Hi", dict(hi=[1]), [1]),
    ("CS", dict(sh=[4]), [4]),
    ("Hi-CS", dict(hi=[1], sh=[4]), [1, 4]),
    ("Th-Hi-CS", dict(hi=[1], sh=[4]), [1, 4]),
    ("Th-Hi", dict(hi=[1], sh=[4]), [1, 4]),
    # n at zenith 60: lights 5, 6, 7 (polar 150..210) see s.n <= 0 (clamped to 0)
    ("SS", dict(n=_dir(60, 0), clamp=True), [5, 6, 7]),
    ("SS-Hi", dict(n=_dir(60, 0), clamp=True, hi=[1]), [1, 5, 6, 7]),
    # n 10 deg from the bisector of light 1 (45x8, t_Re = 22.5), away from the others
    ("Re", dict(k=8, n=_dir(35, 45), hi=[1], hi_add=0.5), [1]),
    ("Re-Hi", dict(k=8, n=_dir(35, 45), hi=[1], hi_add=0.5), [1]),
    ("Th-Re", dict(k=8, n=_dir(35, 45), hi=[1], sh=[5], hi_add=1.5), [1, 5]),
    ("NL", dict(k=4, hi=[1], top=1.0), [1]),            # brightest of a failing quadruple
    ("NL", dict(k=4, sh=[2], top=1.0), [2]),            # darkest when below the Th low bound
    ("NL-Re", dict(k=4, n=_dir(35, 90), hi=[1], hi_add=0.5, top=1.0), [1]),
])
def test_mask_flags_exactly_planted(mask, kw, want):
    img, lay, n, _ = _planted(**kw)
    res = solve(img, lay, mask=mask)
    assert _flags(res) == want
    assert _angle(res.normals[4, 4], n) < 1e-2
    assert res.mask == mask


def test_unflagged_clean_pixels_stay_valid():
    img, lay, n, _ = _planted(hi=[1], sh=[4])
    res = solve(img, lay, mask="Hi-CS")
    # pixels without planted errors (row 1, cols 0..5) keep every observation
    assert res.valid[:, 1, :].all()


def test_sh_flags_cast_and_self_shadows():
    surf = ps.make_surface("spheres", size=64)
    lay = ps.layout("45x8")
    sc = ps.render(surf, lay, model="lambert")
    res = solve(sc.images, lay, mask="Sh", object_mask=surf.object_mask)
    none = solve(sc.images, lay, object_mask=surf.object_mask)
    flagged = ~res.valid
    truth = sc.shadow & surf.object_mask
    assert sc.cast_shadow.any()
    qf = ps.quality_factor(flagged, sc, object_mask=surf.object_mask)
    assert qf["sh"] > 0.8
    # disagreements only within 2 px of the true shadow boundaries
    band = np.stack([ndimage.binary_dilation(t ^ ndimage.binary_erosion(t), iterations=2)
                     for t in truth])
    assert ((flagged ^ truth) & ~band).sum() < 0.01 * truth.sum()
    assert ps.normal_error(res.normals, surf.normals, object_mask=surf.object_mask) < \
        0.5 * ps.normal_error(none.normals, surf.normals, object_mask=surf.object_mask)


def test_sh_masks_self_shadows_too():
    img, lay, n, _ = _planted(k=12, n=_dir(60, 0), clamp=True)
    # a flat height field casts nothing: Sh = self shadows only
    res = solve(img, lay, mask="Sh")
    assert _flags(res) == [5, 6, 7]


# ------------------------------------------------------------- noiseless Lambert
def _gentle(size=64):
    yy, xx = np.mgrid[:size, :size].astype(float)
    c = (size - 1) / 2
    h = 6.0 * np.exp(-((xx - c) ** 2 + (yy - c) ** 2) / (2 * (size / 5) ** 2))
    return ps.surface_from_height(h)


ALL8 = ["None", "Th", "SS", "Re", "CS", "Hi", "Sh", "Hi-Re", "Hi-Re-SS-Sh", "Hi-Re-Sh",
        "Th-Re-Sh", "Th-Hi-Sh", "Th-Hi-Re-Sh", "Th-Hi-Re-SS-Sh", "xNL", "xNL-Sh",
        "xNL-Re-Sh", "xNL-Hi-Sh", "xNL-Hi-Re-Sh", "RA", "Th-CS"]
ALL4 = ["None", "NL", "NL-Re", "Th", "NL-Re-Sh", "NL-Sh", "CJ", "RA", "Hi-Re"]


@pytest.fixture(scope="module")
def lambert8():
    surf = _gentle()
    lay = ps.layout("45x8")
    sc = ps.render(surf, lay, model="lambert", shadows=False)
    assert not sc.shadow.any()
    return surf, lay, sc


@pytest.fixture(scope="module")
def lambert4():
    surf = _gentle()
    lay = ps.layout("30x4")
    sc = ps.render(surf, lay, model="lambert", shadows=False)
    assert not sc.shadow.any()
    return surf, lay, sc


@pytest.mark.parametrize("mask", ALL8)
@pytest.mark.parametrize("weighted", [False, True])
def test_noiseless_lambert_exact_8(lambert8, mask, weighted):
    surf, lay, sc = lambert8
    res = solve(sc.images, lay, mask=mask, weighted=weighted)
    assert (res.valid.sum(axis=0) >= 3).all()
    assert ps.normal_error(res.normals, surf.normals) < 0.01
    assert np.isfinite(res.normals).all() and np.isfinite(res.residual).all()


@pytest.mark.parametrize("mask", ALL4)
def test_noiseless_lambert_exact_4(lambert4, mask):
    surf, lay, sc = lambert4
    res = solve(sc.images, lay, mask=mask)
    assert ps.normal_error(res.normals, surf.normals) < 0.01


@pytest.mark.parametrize("scope", ["image", "object", "robust", "pixel"])
def test_noiseless_lambert_exact_scopes(lambert8, scope):
    surf, lay, sc = lambert8
    res = solve(sc.images, lay, mask="Th-Hi-CS", th_scope=scope, object_mask=surf.object_mask)
    assert ps.normal_error(res.normals, surf.normals) < 0.01
    assert res.info["th_scope"] == scope


def test_fwlse_noiseless_lambert_exact(lambert8):
    surf, lay, sc = lambert8
    res = solve(sc.images, lay, method="fwlse")
    assert ps.normal_error(res.normals, surf.normals) < 0.01


# ------------------------------------------------------------- Eq. 3.1
def test_complete_three_adds_least_residual():
    lay = ps.layout("45x8")
    n = _dir(20, 30)
    L = (lay.S @ n).astype(np.float32)
    img = np.broadcast_to(L[:, None, None], (8, 1, 2)).copy()
    img[3, 0, 0] += 0.05   # small error: least-residual candidate after the exact ones
    img[6, 0, 0] += 1.0
    img[2, 0, 0] -= 0.5
    S = lay.S
    b0 = kernel.ls(img, S)
    r = np.abs(kernel.residuals(img, b0, S))
    valid = np.zeros((8, 1, 2), dtype=bool)
    valid[[0, 1], 0, 0] = True          # pixel 0: two valid
    valid[:, 0, 1] = True               # pixel 1: all valid, untouched
    out = kernel.complete_three(valid, r)
    assert out[:, 0, 0].sum() == 3
    masked = [i for i in range(8) if i not in (0, 1)]
    best = masked[int(np.argmin(r[masked, 0, 0]))]
    assert out[best, 0, 0]
    assert out[:, 0, 1].all()
    # the cached completion used by solve() is the same rule
    got = _Completer(img, S)(valid.reshape(8, -1).copy()).reshape(8, 1, 2)
    assert np.array_equal(got, out)


def test_completer_matches_kernel_random():
    rng = np.random.default_rng(1)
    lay = ps.layout("30x8+60x8")
    img = rng.random((16, 20, 30), dtype=np.float32)
    valid = rng.random((16, 20, 30)) < 0.12
    r = kernel.residuals(img, kernel.ls(img, lay.S), lay.S)
    want = kernel.complete_three(valid, r)
    got = _Completer(img, lay.S)(valid.reshape(16, -1).copy()).reshape(valid.shape)
    assert np.array_equal(got, want)
    assert (got.sum(axis=0) >= 3).all()


def test_every_pixel_keeps_three_observations():
    surf = ps.make_surface("sombrero", size=64)
    lay = ps.layout("45x8")
    sc = ps.render(surf, lay)
    for mask in ["Th", "Th-Hi-Re-Sh", "xNL-Hi-Re-Sh", "RA-Th"]:
        res = solve(sc.images, lay, mask=mask, object_mask=surf.object_mask)
        assert (res.valid.sum(axis=0) >= 3).all(), mask
        assert np.isfinite(res.normals).all()


# ------------------------------------------------------------- TS scenes
@pytest.fixture(scope="module")
def ts_semisphere():
    # 128 px: the weighting kernels (disk radius 7, Gaussian sigma 3, 15 x 15) were
    # chosen for 512 px images; much smaller images make them coarse
    surf = ps.make_surface("semisphere_disc", size=128)
    lay = ps.layout("45x8")
    return surf, lay, ps.render(surf, lay, model="ts")


def _boundary_energy(normals, valid, region):
    """Sum of squared finite differences of the normals within 2 px of the binary mask's
    boundaries, inside ``region``."""
    edge = np.zeros(valid.shape[1:], bool)
    for v in valid:
        edge |= v ^ ndimage.binary_erosion(v)
    band = ndimage.binary_dilation(edge, iterations=2) & region
    gx = np.diff(normals, axis=1)[:-1]
    gy = np.diff(normals, axis=0)[:, :-1]
    e = (gx ** 2).sum(-1) + (gy ** 2).sum(-1)
    return float(e[band[:-1, :-1]].sum())


def test_weighted_th_removes_false_edges(ts_semisphere):
    surf, lay, sc = ts_semisphere
    binary = solve(sc.images, lay, mask="Th", object_mask=surf.object_mask)
    weighted = solve(sc.images, lay, mask="Th", object_mask=surf.object_mask, weighted=True)
    assert np.array_equal(weighted.valid, binary.valid)
    assert weighted.weights is not None and weighted.weights.dtype == np.float32
    region = ndimage.binary_erosion(surf.object_mask, iterations=3)
    e_bin = _boundary_energy(binary.normals, binary.valid, region)
    e_w = _boundary_energy(weighted.normals, binary.valid, region)
    e_true = _boundary_energy(surf.normals, binary.valid, region)
    assert e_w < 0.5 * e_bin
    assert e_w < 2.0 * e_true
    ne_b = ps.normal_error(binary.normals, surf.normals, object_mask=surf.object_mask)
    ne_w = ps.normal_error(weighted.normals, surf.normals, object_mask=surf.object_mask)
    assert ne_w <= ne_b + 0.2


def test_fwlse_converges_and_beats_none(ts_semisphere):
    surf, lay, sc = ts_semisphere
    none = solve(sc.images, lay, object_mask=surf.object_mask)
    res = solve(sc.images, lay, method="fwlse", object_mask=surf.object_mask, max_iter=30)
    assert res.info["converged"] is True
    assert 1 <= res.iterations < 30
    assert ps.normal_error(res.normals, surf.normals, object_mask=surf.object_mask) < \
        ps.normal_error(none.normals, surf.normals, object_mask=surf.object_mask)
    assert res.weights.shape == sc.images.shape


@pytest.mark.parametrize("mask", ["Th", "Th-Hi-Re-Sh", "Hi-Re-SS-Sh", "xNL-Hi-Re-Sh", "RA"])
def test_masks_beat_none_on_ts(ts_semisphere, mask):
    surf, lay, sc = ts_semisphere
    none = solve(sc.images, lay, object_mask=surf.object_mask)
    res = solve(sc.images, lay, mask=mask, object_mask=surf.object_mask)
    assert ps.normal_error(res.normals, surf.normals, object_mask=surf.object_mask) < \
        ps.normal_error(none.normals, surf.normals, object_mask=surf.object_mask)


def test_iteration_stops_when_masks_stop_changing(ts_semisphere):
    surf, lay, sc = ts_semisphere
    res = solve(sc.images, lay, mask="Hi-Re", object_mask=surf.object_mask, max_iter=50,
                truth_normals=surf.normals, iter_tol=0)
    assert res.info["converged"] in (True, "cycle")
    assert res.iterations < 50
    assert len(res.info["ne"]) == res.iterations + 2  # first solve, rounds, final
    one = solve(sc.images, lay, mask="Hi-Re", object_mask=surf.object_mask, max_iter=1)
    assert one.iterations <= 1
    # the default tolerance stops once a round changes <= 0.1 % of the object pixels
    tol = solve(sc.images, lay, mask="Hi-Re-Sh", object_mask=surf.object_mask)
    assert tol.info["converged"] in (True, "cycle", "tol")
    last = tol.info["changed"][-1]
    assert last == 0 or last <= 1e-3 * surf.object_mask.sum() or tol.info["converged"] == "cycle"


def test_th_offset_literal_equal_when_min_is_zero(ts_semisphere):
    surf, lay, sc = ts_semisphere
    a = solve(sc.images, lay, mask="Th")  # literal Eq. 3.2 (default)
    b = solve(sc.images, lay, mask="Th", th_offset=True)
    assert np.array_equal(a.valid, b.valid)

    # with an ambient offset only the offset rule keeps the same mask (before Eq. 3.1)
    def th(img, offset):
        rg = ranges(img, offset=offset)
        return th_mask(img, rg["lo"], rg["rng"], 0.06, 0.35)
    base = th(sc.images, True)
    assert np.array_equal(base, th(sc.images + 0.3, True))
    assert not np.array_equal(base, th(sc.images + 0.3, False))


def test_th_scopes_differ_on_one_specular_spot():
    lay = ps.layout("45x8")
    img, _, _, _ = _planted(k=8, top=1.0, size=20)
    img[:, :2] = 0.0     # 10 % dark background
    img[:, 18:] = 2.5    # 10 % bright pixels: the robust range is [0, 2.5]
    img[0, 15, 15] = 50.0  # one specular spot sets image 0's range
    im = solve(img, lay, mask="Th", th_scope="image")
    rb = solve(img, lay, mask="Th", th_scope="robust")
    # image scope: image 0's bounds are inflated -> its diffuse pixels fall below k_low*range
    assert (~im.valid[0, 2:5, 2:5]).all()
    assert rb.valid[0, 2:5, 2:5].all()


def test_pixel_scope_is_albedo_invariant():
    lay = ps.layout("45x8")
    img, _, n, _ = _planted(k=8, sh=[4], top=1.0)
    img2 = img.copy()
    img2[:, 2:, 2:] *= 0.05  # dark albedo patch
    a = solve(img2, lay, mask="Th", th_scope="pixel")
    assert _flags(a) == [4]
    b = solve(img2, lay, mask="Th", th_scope="image")
    assert len(_flags(b)) == 8 or _flags(b) != [4]


def test_object_scope_ignores_pixels_outside_the_object():
    lay = ps.layout("45x8")
    img, _, _, _ = _planted(k=8, hi=[1], sh=[4], top=3.0, size=12)
    img[:, 0, 2] = 40.0  # a bright spot outside the object
    om = np.ones((12, 12), bool)
    om[0, 2] = False
    im = solve(img, lay, mask="Th", th_scope="image", object_mask=om)
    ob = solve(img, lay, mask="Th", th_scope="object", object_mask=om)
    assert _flags(ob) == [1, 4]
    assert _flags(im) != [1, 4]  # the spot inflates every image's range


def test_sh_lit_and_unoccluded_matches_ss_and_not_occluded():
    """The Sh mask's block-wise test gives exactly ss(b, S) & ~occluded, also in place
    and when the pixel count is not a multiple of the block."""
    from psbench.solve.masks import sh as sh_mask
    from psbench.solve.masks.ss import ss

    rng = np.random.default_rng(3)
    b = rng.standard_normal((181, 190, 3)).astype(np.float32)     # 34390 px > 1 block
    S = rng.standard_normal((16, 3)).astype(np.float32)
    occ = rng.random((16, 181, 190)) < 0.2
    want = ss(b, S) & ~occ
    assert 0 < want.mean() < 1
    assert np.array_equal(sh_mask.lit_and_unoccluded(b, S, occ), want)
    inplace = occ.copy()
    assert sh_mask.lit_and_unoccluded(b, S, inplace, out=inplace) is inplace
    assert np.array_equal(inplace, want)
