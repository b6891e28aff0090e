"""Tests for psbench.solve.wps (weighted multi-zenith PS, Section 4.3)."""
import numpy as np
import pytest

from psbench._shared.checks import PsbenchError
from psbench.lights import layout
from psbench.metrics import normal_error, normal_error_map
from psbench.solve import kernel
from psbench.solve.methods.wps import WEIGHTS, sig, surface_factor, wps

WEIGHTED = ("e", "eZsource", "eZsurface", "eZsourceZsurface")


def _dome(H=40, slope=0.4):
    """Normals of a smooth bump with surface zenith below 30 degrees everywhere."""
    yy, xx = np.mgrid[-1:1:H * 1j, -1:1:H * 1j]
    n = np.stack([xx * slope, -yy * slope * 0.7, np.ones_like(xx)], -1)
    return (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)


def _scene(spec="30x8+60x8", H=40, slope=0.4, noise=0.0, seed=0, rho=0.8):
    lay = layout(spec)
    n = _dome(H, slope)
    I = np.asarray(kernel.lambert((rho * n).astype(np.float32), lay.S), dtype=np.float32)
    if noise:
        rng = np.random.default_rng(seed)
        I = I + rng.normal(0, noise, I.shape).astype(np.float32)
    return I, lay, n


@pytest.fixture(scope="module")
def ts_scene():
    """A small TS sombrero with highlights, shadows and 5 % noise."""
    from psbench.render import render
    from psbench.surfaces import make_surface
    surf = make_surface("sombrero2", size=64)
    lay = layout("30x8+60x8")
    sc = render(surf, lay, model="ts", shadows=True, noise=0.05, seed=3)
    return sc.images, lay, surf


@pytest.mark.parametrize("weight", WEIGHTS)
@pytest.mark.parametrize("binary", [False, True])
def test_noiseless_lambert_exact(weight, binary):
    I, lay, n = _scene()
    assert I.min() > 0  # no shadows
    r = wps(I, lay, weight=weight, binary=binary, truth_normals=n)
    assert r.method == "wps"
    assert normal_error(r.normals, n) < 0.01
    assert np.allclose(r.albedo, 0.8, atol=1e-3)
    assert r.ring_weights.shape == (2,) + I.shape[1:]
    assert r.ring_normals.shape == (2,) + I.shape[1:] + (3,)
    assert r.ring_albedo.shape == r.ring_residual.shape == (2,) + I.shape[1:]
    assert np.allclose(r.ring_weights.sum(0), 1.0, atol=1e-5)


@pytest.mark.parametrize("weight", WEIGHTS)
def test_weights_sum_to_one_and_nonnegative(ts_scene, weight):
    I, lay, surf = ts_scene
    for binary in (False, True):
        r = wps(I, lay, weight=weight, binary=binary, truth_normals=surf.normals)
        assert (r.ring_weights >= 0).all()
        assert np.allclose(r.ring_weights.sum(0), 1.0, atol=1e-5)
        if binary:
            assert set(np.unique(r.ring_weights)) <= {0.0, 1.0} or weight == "None"


def test_e_weights_match_eq_4_13(ts_scene):
    I, lay, _ = ts_scene
    r = wps(I, lay, weight="e")
    e1, e2 = r.ring_residual.astype(np.float64)
    w1 = e2 ** 2 / (e1 ** 2 + e2 ** 2)
    assert np.allclose(r.ring_weights[0], w1, atol=1e-4)
    assert np.allclose(r.ring_weights[1], 1 - w1, atol=1e-4)


def test_ezsource_weights_match_eq_4_14(ts_scene):
    I, lay, _ = ts_scene
    r = wps(I, lay, weight="eZsource")
    e1, e2 = r.ring_residual.astype(np.float64)
    u1 = np.sin(np.radians(30)) * e2 ** 2
    u2 = np.sin(np.radians(60)) * e1 ** 2
    assert np.allclose(r.ring_weights[0], u1 / (u1 + u2), atol=1e-4)


def test_ezsourcezsurface_uses_sin_z2_and_mirrored_sigmoid(ts_scene):
    I, lay, _ = ts_scene
    r = wps(I, lay, weight="eZsourceZsurface")
    e1, e2 = r.ring_residual.astype(np.float64)
    z1 = np.degrees(np.arccos(np.clip(r.ring_normals[0][..., 2], -1, 1))) / 90
    z2 = np.degrees(np.arccos(np.clip(r.ring_normals[1][..., 2], -1, 1))) / 90
    s = lambda x: 1 / (1 + np.exp(-10 * (x - 0.5)))  # noqa: E731
    u1 = np.sin(np.radians(30)) * s(z1) * e2 ** 2
    u2 = np.sin(np.radians(60)) * s(1 - z2) * e1 ** 2
    assert np.allclose(r.ring_weights[0], u1 / (u1 + u2), atol=2e-3)


def test_binary_picks_lower_residual_ring(ts_scene):
    I, lay, _ = ts_scene
    r = wps(I, lay, weight="e", binary=True)
    low = np.argmin(r.ring_residual, axis=0)
    assert np.array_equal(np.argmax(r.ring_weights, axis=0), low)
    # the fused normal is that ring's normal
    pick = np.take_along_axis(r.ring_normals, low[None, ..., None], 0)[0]
    assert np.allclose(pick, r.normals, atol=1e-5)


def test_surface_factor_follows_fig_4_11():
    z = np.array([0.0, 15, 30, 45, 60, 75, 90])
    low = surface_factor(z, 0.0)
    high = surface_factor(z, 1.0)
    assert np.all(np.diff(low) > 0) and np.all(np.diff(high) < 0)
    assert np.isclose(low[3], 0.5) and np.isclose(high[3], 0.5)
    assert np.allclose(surface_factor(z, 0.5), 0.5)
    assert np.isclose(sig(0.5), 0.5) and sig(1.0) > 0.99 and sig(0.0) < 0.01


def test_ezsurface_favours_high_ring_on_smooth_and_low_ring_on_steep():
    # equal noise on both rings, no highlights or shadows: the weight difference between
    # smooth and steep pixels comes from the sigmoid
    I, lay, n = _scene(H=64, slope=0.55, noise=0.01, seed=1)
    r = wps(I, lay, weight="eZsurface")
    zen = np.degrees(np.arccos(n[..., 2]))
    smooth, steep = zen < 10, zen > 30
    assert smooth.sum() > 20 and steep.sum() > 20
    w_low = r.ring_weights[0]
    assert w_low[smooth].mean() < 0.2
    assert w_low[steep].mean() > 5 * w_low[smooth].mean()


def test_oracle_never_worse_than_any_weighting(ts_scene):
    I, lay, surf = ts_scene
    m = surf.object_mask
    orc = wps(I, lay, weight="oracle", truth_normals=surf.normals)
    e_or = normal_error_map(orc.normals, surf.normals)
    for weight in WEIGHTED:
        for binary in (False, True):
            r = wps(I, lay, weight=weight, binary=binary)
            e = normal_error_map(r.normals, surf.normals)
            assert (e_or <= e + 1e-3).all(), (weight, binary)
            assert normal_error(orc.normals, surf.normals, object_mask=m) <= normal_error(r.normals, surf.normals, object_mask=m)
    for j in range(2):
        assert (e_or <= normal_error_map(orc.ring_normals[j], surf.normals) + 1e-3).all()
    orb = wps(I, lay, weight="oracle", binary=True, truth_normals=surf.normals)
    best = np.minimum(*[normal_error_map(orc.ring_normals[j], surf.normals) for j in range(2)])
    assert np.allclose(normal_error_map(orb.normals, surf.normals), best, atol=1e-3)


def test_three_rings():
    I, lay, n = _scene("30x4+45x4+60x4")
    for weight in WEIGHTS:
        r = wps(I, lay, weight=weight, truth_normals=n)
        assert r.ring_weights.shape == (3,) + I.shape[1:]
        assert np.allclose(r.ring_weights.sum(0), 1.0, atol=1e-5)
        assert normal_error(r.normals, n) < 0.01
    # R = 3, weight e: w_j ∝ 1/e_j^2
    I, lay, n = _scene("30x4+45x4+60x4", noise=0.02)
    r = wps(I, lay, weight="e")
    inv = 1 / r.ring_residual.astype(np.float64) ** 2
    assert np.allclose(r.ring_weights, inv / inv.sum(0), atol=1e-4)


def test_three_rings_oracle_never_worse():
    from psbench.render import render
    from psbench.surfaces import make_surface
    surf = make_surface("sombrero3", size=48)
    lay = layout("30x4+45x4+60x4")
    sc = render(surf, lay, noise=0.05, seed=1)
    orc = wps(sc.images, lay, weight="oracle", truth_normals=surf.normals)
    e_or = normal_error_map(orc.normals, surf.normals)
    for weight in WEIGHTED:
        e = normal_error_map(wps(sc.images, lay, weight=weight).normals, surf.normals)
        assert (e_or <= e + 1e-3).all()


def test_none_is_plain_ps_over_all_images(ts_scene):
    I, lay, _ = ts_scene
    r = wps(I, lay, weight="None")
    n_ps, _ = kernel.split(kernel.ls(I, lay.S))
    assert np.allclose(r.normals, n_ps, atol=1e-5)
    assert np.allclose(r.ring_weights, 0.5)


def test_errors():
    I, lay, n = _scene()
    with pytest.raises(PsbenchError, match="single ring"):
        wps(I[:8], layout("45x8"))
    with pytest.raises(PsbenchError, match="at least 3"):
        I2, lay2, _ = _scene("30x2+60x8")
        wps(I2, lay2)
    with pytest.raises(PsbenchError, match="eZsourceZsurface"):
        wps(I, lay, weight="bogus")
    with pytest.raises(PsbenchError, match="truth_normals"):
        wps(I, lay, weight="oracle")
    with pytest.raises(PsbenchError):
        wps(I[:15], lay)
    with pytest.raises(PsbenchError):
        wps(I, lay, object_mask=np.zeros((3, 3), bool))


def test_object_mask_and_solve_delegation(ts_scene):
    from psbench.solve import solve
    I, lay, surf = ts_scene
    r = solve(I, lay, method="wps", weight="eZsourceZsurface", object_mask=surf.object_mask)
    assert r.method == "wps" and r.ring_weights.shape[0] == 2
    out = ~surf.object_mask
    assert np.allclose(r.normals[out], (0, 0, 1)) and (r.albedo[out] == 0).all()
    direct = wps(I, lay, object_mask=surf.object_mask)
    assert np.allclose(direct.normals, r.normals)


def test_masked_rings(ts_scene):
    I, lay, surf = ts_scene
    r = wps(I, lay, mask="Th", weight="e")
    assert r.mask == "Th"
    assert not r.valid.all()
    assert np.allclose(r.ring_weights.sum(0), 1.0, atol=1e-5)
    assert np.isfinite(r.normals).all()


def test_residuals_match_explicit_computation(ts_scene):
    I, lay, _ = ts_scene
    r = wps(I, lay, weight="eZsourceZsurface")
    S = lay.S
    for j, idx in enumerate(lay.rings()):
        b = r.ring_normals[j] * r.ring_albedo[j][..., None]
        e = np.sqrt(((I[idx] - kernel.lambert(b, S[idx])) ** 2).mean(0))
        assert np.allclose(r.ring_residual[j], e, rtol=1e-3, atol=1e-5)
    res = np.sqrt(((I - kernel.lambert(r.normals * r.albedo[..., None], S)) ** 2).sum(0))
    assert np.allclose(r.residual, res, rtol=1e-3, atol=1e-4)


def test_weights_per_observation_ring_weights_per_ring(ts_scene):
    """One name per concept: ``weights`` (k, H, W) per observation (from the rings'
    weighted solves) or None; ``ring_weights`` (rings, H, W)."""
    I, lay, surf = ts_scene
    plain = wps(I, lay)
    assert plain.weights is None and plain.ring_weights.shape == (2,) + I.shape[1:]
    w = wps(I, lay, mask="Th", weighted=True, object_mask=surf.object_mask)
    assert w.weights.shape == I.shape and w.weights.dtype == np.float32
    assert (w.weights[:, ~surf.object_mask] == 0).all() and (w.weights[:, surf.object_mask] > 0).all()
    assert w.ring_weights.shape == (2,) + I.shape[1:]
    assert set(w.thresholds) == {"ring0", "ring1"} and w.converged is True
    assert "rings=2" in repr(w)


@pytest.mark.parametrize("R", [2, 3, 5])
def test_binary_weights_are_the_first_maximum(R):
    from psbench.solve.methods.wps._kernel import _one_hot

    u = np.random.default_rng(R).random((R, 500))
    u[:, :20] = 0.5                                   # ties: the earlier ring, as argmax
    ref = np.zeros_like(u)
    ref[np.argmax(u, axis=0), np.arange(500)] = 1.0
    _one_hot(u, 500, np.empty(500), np.empty(500))
    np.testing.assert_array_equal(u, ref)


def test_weight_none_is_least_squares_over_every_image():
    """2Z PS (weight None) without a mask is plain PS on all images, here computed from
    the ring solutions without another pass over the images."""
    import psbench as ps

    surf = ps.make_surface("sombrero2", size=48)
    lay = ps.layout("30x8+60x8")
    sc = ps.render(surf, lay, model="ts", noise=0.05, seed=0)
    w = ps.solve(sc.images, lay, method="wps", weight="None", object_mask=surf.object_mask)
    p = ps.solve(sc.images, lay, object_mask=surf.object_mask)
    m = surf.object_mask
    np.testing.assert_allclose(w.normals[m], p.normals[m], atol=1e-5)
    np.testing.assert_allclose(w.albedo[m], p.albedo[m], rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(w.residual[m], p.residual[m], rtol=1e-3, atol=1e-4)


# --- the compiled kernel against a numpy reference of Eqs. 4.10-4.16 and the oracle ----

def _ref_arc(n1, n2, r):
    a1, a2, c = (n1 * r).sum(0), (n2 * r).sum(0), (n1 * n2).sum(0)
    den = 1.0 - c * c
    ok = den > 1e-12
    den = np.where(ok, den, 1.0)
    al, be = (a1 - c * a2) / den, (a2 - c * a1) / den
    inside = ok & (al >= 0) & (be >= 0) & ((al + be) > 0)
    p = al * n1 + be * n2
    pn = np.sqrt((p * p).sum(0))
    cos_in = np.where(inside, (p * r).sum(0) / np.where(inside, pn, 1.0), -2.0)
    use1 = a1 >= a2
    c1 = np.where(inside, al, np.where(use1, 1.0, 0.0))
    c2 = np.where(inside, be, np.where(use1, 0.0, 1.0))
    return c1, c2, np.where(inside, cos_in, np.maximum(a1, a2))


def _ref_oracle(B, r, binary):
    """numpy reference of the oracle (float64): best single ring, arcs, cones of three."""
    import itertools
    R, _, N = B.shape
    rho = np.sqrt((B * B).sum(1))
    n = B / np.maximum(rho, 1e-30)[:, None]
    r = r / np.maximum(np.sqrt((r * r).sum(0)), 1e-30)
    cs = (n * r[None]).sum(1)
    best = np.argmax(cs, axis=0)
    bestcos = np.take_along_axis(cs, best[None], 0)[0]
    C = np.zeros((R, N))
    C[best, np.arange(N)] = 1.0
    if not binary:
        for i, j in itertools.combinations(range(R), 2):
            c1, c2, cos = _ref_arc(n[i], n[j], r)
            better = cos > bestcos
            C[:, better] = 0.0
            C[i, better], C[j, better] = c1[better], c2[better]
            bestcos = np.where(better, cos, bestcos)
        for tri in itertools.combinations(range(R), 3):
            M = np.moveaxis(np.stack([n[t] for t in tri], axis=-1), 1, 0)
            ok = np.abs(np.linalg.det(M)) > 1e-9
            coef = np.zeros((N, 3))
            coef[ok] = np.linalg.solve(M[ok], r.T[ok][..., None])[..., 0]
            inside = ok & (coef >= 0).all(axis=1) & (bestcos < 1.0)
            C[:, inside] = 0.0
            for q, t in enumerate(tri):
                C[t, inside] = coef[inside, q]
            bestcos = np.where(inside, 1.0, bestcos)
    w = C / np.maximum(rho, 1e-30)
    s = w.sum(0)
    return np.where(s > 0, w / np.where(s > 0, s, 1.0), 1.0 / R)


def _ref_weights(weight, binary, B, e2, zen, rank, z_scale=90.0, truth=None):
    """numpy reference of the ring weights (float64) from ring b (R, 3, N), e^2 (R, N)."""
    R, _, N = B.shape
    if weight == "oracle":
        return _ref_oracle(B, truth, binary)
    u = 1.0 / (e2 + 1e-30)
    for j in range(R):
        if weight in ("eZsource", "eZsourceZsurface"):
            u[j] *= np.sin(np.radians(zen[j]))
        if weight in ("eZsurface", "eZsourceZsurface"):
            rho = np.sqrt((B[j] ** 2).sum(0))
            zs = np.degrees(np.arccos(np.clip(B[j, 2] / np.maximum(rho, 1e-30), -1, 1)))
            z, t = zs / z_scale, rank[j]
            u[j] *= 1.0 / (1.0 + np.exp(-10.0 * ((1 - t) * z + t * (1 - z) - 0.5)))
    if binary:
        w = np.zeros_like(u)
        w[np.argmax(u, axis=0), np.arange(N)] = 1.0
        return w
    return u / u.sum(0)


def _kernel_weights(weight, binary, B, e2, lay, truth=None, z_scale=90.0):
    """The compiled weights (masked path's kernel) on given float32 ring b and e^2."""
    from psbench.solve.methods.wps import _kernel as K
    from psbench.solve.methods.wps import method as W
    R, _, N = B.shape
    rings = W._rings(lay)
    zen, args = W._ring_setup(lay, rings, W.WPSOptions(weight=weight, binary=binary,
                                                        z_scale=z_scale),
                              None if truth is None else truth.T.reshape(1, N, 3), N)
    w = np.empty((R, N), dtype=np.float32)
    K.weigh_rings(B, e2, *args, np.empty((N, 3), np.float32), w,
                  np.empty((R, N, 3), np.float32), np.empty((R, N), np.float32),
                  np.empty((R, N), np.float32))
    return w, zen


@pytest.mark.parametrize("spec", ["30x8+60x8", "30x4+45x4+60x4"])
@pytest.mark.parametrize("weight", WEIGHTED)
@pytest.mark.parametrize("z_scale", [90.0, 40.0])
def test_kernel_weights_match_numpy_reference(spec, weight, z_scale):
    rng = np.random.default_rng(7)
    lay = layout(spec)
    R, N = len(lay.rings()), 3000
    n = rng.normal(size=(R, 3, N))
    n[:, 2] = np.abs(n[:, 2]) + 0.3          # zeniths across 0-90 degrees
    B = (n / np.linalg.norm(n, axis=1, keepdims=True) * rng.uniform(0.2, 1, (R, 1, N)))
    B = B.astype(np.float32)
    e2 = (10.0 ** rng.uniform(-6, -1, (R, N))).astype(np.float32)
    from psbench.solve.methods.wps.method import _ranks
    zen, rank = _ranks(lay, lay.rings())
    for binary in (False, True):
        w, _ = _kernel_weights(weight, binary, B, e2, lay, z_scale=z_scale)
        ref = _ref_weights(weight, binary, B.astype(np.float64), e2.astype(np.float64), zen,
                           rank, z_scale)
        np.testing.assert_allclose(w, ref, rtol=2e-6, atol=1e-7)


@pytest.mark.parametrize("R", [2, 3, 4])
def test_kernel_oracle_matches_numpy_reference(R):
    from psbench.solve.methods.wps import oracle_weights
    rng = np.random.default_rng(R)
    N = 4000
    truth = rng.normal(size=(3, N))
    truth[2] = np.abs(truth[2]) + 0.5
    truth /= np.linalg.norm(truth, axis=0)
    # ring normals scattered around the truth, so that every case occurs (inside an arc
    # or a cone of three, on an edge, single ring)
    B = truth[None] + rng.normal(scale=0.3, size=(R, 3, N))
    B *= rng.uniform(0.3, 1.0, (R, 1, N))
    B = B.astype(np.float32)
    t32 = truth.astype(np.float32)
    for binary in (False, True):
        w = oracle_weights(B, t32, binary=binary)
        ref = _ref_oracle(B.astype(np.float64), t32.astype(np.float64), binary)
        np.testing.assert_allclose(w, ref, rtol=1e-5, atol=1e-6)


def test_plain_pass_matches_ring_least_squares_and_its_own_weights(ts_scene):
    """The one-pass kernel: every ring's least squares and RMS residual (numpy lstsq,
    float64), and weights equal to the compiled weights of those ring solutions."""
    I, lay, surf = ts_scene
    k, H, W = I.shape
    N = H * W
    for weight in WEIGHTS:
        r = wps(I, lay, weight=weight, truth_normals=surf.normals)
        B = np.empty((2, 3, N), np.float32)
        e2 = np.empty((2, N), np.float32)
        for j, idx in enumerate(lay.rings()):
            Ij = I[idx].reshape(idx.size, N).astype(np.float64)
            bj, *_ = np.linalg.lstsq(lay.S[idx].astype(np.float64), Ij, rcond=None)
            ej = np.sqrt(((Ij - lay.S[idx] @ bj) ** 2).mean(0))
            got = (r.ring_normals[j] * r.ring_albedo[j][..., None]).reshape(N, 3).T
            np.testing.assert_allclose(got, bj, atol=2e-6)
            np.testing.assert_allclose(r.ring_residual[j].ravel(), ej, rtol=1e-4, atol=1e-6)
            B[j], e2[j] = bj, ej ** 2
        w, _ = _kernel_weights(weight, False, B, e2, lay,
                               truth=surf.normals.reshape(N, 3).T if weight == "oracle" else None)
        np.testing.assert_allclose(r.ring_weights.reshape(2, N), w,
                                   atol=1e-3 if weight == "oracle" else 1e-5)


@pytest.mark.parametrize("weight", WEIGHTS)
def test_kernel_results_do_not_depend_on_threads_or_block_edges(weight):
    """Bit-identical outputs for 1 and 2 threads, on a size that is no multiple of the
    kernel's pixel block."""
    import numba
    I, lay, n = _scene(H=37, noise=0.02, seed=3)
    fields = ("normals", "albedo", "residual", "ring_weights", "ring_normals", "ring_albedo",
              "ring_residual")
    runs = []
    old = numba.get_num_threads()
    try:
        for t in (1, min(2, numba.config.NUMBA_NUM_THREADS)):
            numba.set_num_threads(t)
            r = wps(I, lay, weight=weight, truth_normals=n)
            runs.append({f: getattr(r, f) for f in fields})  # ring outputs: read now
    finally:
        numba.set_num_threads(old)
    a, b = runs
    for f in fields:
        np.testing.assert_array_equal(a[f], b[f], err_msg=f)


@pytest.mark.parametrize("weight", ["e", "oracle"])
def test_ring_outputs_on_demand_equal_the_pass_that_writes_everything(ts_scene, weight):
    """Without a mask the ring normals / albedo / residual are computed when first read;
    they are bit-identical to the one pass writing every output, and computed once."""
    from psbench.solve.methods.wps import _kernel as K
    from psbench.solve.methods.wps import method as W

    I, lay, surf = ts_scene
    k, H, Wd = I.shape
    N = H * Wd
    r = wps(I, lay, weight=weight, truth_normals=surf.normals)
    assert "_lazy_ring_normals" in r.__dict__ and callable(r.__dict__["_lazy_ring_normals"])
    rings = lay.rings()
    _, args = W._ring_setup(lay, rings, W.WPSOptions(weight=weight),
                            surf.normals.astype(np.float32), N)
    b, w, rn, ra, re = W._outputs(2, N)
    K.plain_rings(I.reshape(k, N), *W._constants(lay.S.astype(np.float64), rings), *args, b,
                  np.empty(N, np.float32), w, rn, ra, re)
    np.testing.assert_array_equal(r.ring_weights.reshape(2, N), w)
    np.testing.assert_array_equal(r.ring_normals, rn.reshape(2, H, Wd, 3))
    np.testing.assert_array_equal(r.ring_albedo, ra.reshape(2, H, Wd))
    np.testing.assert_array_equal(r.ring_residual, re.reshape(2, H, Wd))
    assert r.ring_normals is r.ring_normals


def test_fully_clipped_ring_takes_the_whole_weight():
    """Saturation is not treated (the docstring says so): where every image of a ring
    is clipped, that ring's constant observations fit the flat normal exactly, and the
    residual weights give it everything; elsewhere the weights are shared."""
    I, lay, n = _scene(noise=0.01)
    clipped = np.zeros(I.shape[1:], bool)
    clipped[:, :20] = True
    ring0 = lay.rings()[0]
    I = I.copy()
    I[ring0] = np.where(clipped, np.float32(1.0), I[ring0])
    r = wps(I, lay)
    assert np.allclose(r.ring_weights[0][clipped], 1.0, atol=1e-6)
    assert np.allclose(r.normals[clipped], [0, 0, 1], atol=1e-5)
    assert r.ring_weights[0][~clipped].max() < 0.99
