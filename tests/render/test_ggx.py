"""GGX lobe (psbench.render._ggx, render(model="ggx")) against independent numeric checks."""
import numpy as np
import pytest

import psbench as ps
from psbench._shared.checks import PsbenchError
from psbench.render._ggx import ggx_d, ggx_specular, smith_g1


def _sphere_dirs(n_theta=400, n_phi=200, top=np.pi / 2):
    """Midpoint quadrature of the directions within ``top`` of +z (the upper hemisphere
    by default): unit directions (N, 3), solid-angle weights (N,)."""
    th = (np.arange(n_theta) + 0.5) * top / n_theta
    ph = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    T, P = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    w = (np.sin(T) * (top / n_theta) * (2 * np.pi / n_phi)).ravel()
    return d, w


@pytest.mark.parametrize("alpha", [0.2, 0.5, 0.9])
def test_distribution_is_normalized(alpha):
    # the projected microfacet area equals the macro surface: int D (n.h) dw_h = 1
    h, w = _sphere_dirs(2000, 8)
    val = np.sum(ggx_d(h[:, 2].astype(np.float64), alpha) * h[:, 2] * w)
    assert val == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("alpha,view_deg", [(0.3, 0.0), (0.3, 60.0), (0.6, 80.0)])
def test_weak_white_furnace(alpha, view_deg):
    # Heitz 2014, Eq. 32 (weak white furnace): int G1(v) D(h) / (4 |n.v|) dw_l = 1 for
    # every view v, over the whole sphere of l (reflections about tilted facets go
    # below), facets facing v and n only; the visible-normal normalization in l-space
    t = np.radians(view_deg)
    v = np.array([np.sin(t), 0.0, np.cos(t)])
    l, w = _sphere_dirs(2400, 600, top=np.pi)
    h = l + v
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    front = (h @ v > 0) & (h[:, 2] > 0)
    val = np.sum(smith_g1(v[2], alpha) * ggx_d(h[:, 2], alpha) * front / (4 * v[2]) * w)
    assert val == pytest.approx(1.0, abs=0.02)


def _albedo_half_vector(alpha, v):
    """Directional albedo of the BRDF with F = 1, integrated over half vectors h
    (l = 2 (v.h) h - v, dw_l = 4 (v.h) dw_h) with the tan-form D and Smith G1: an
    independent parameterization and spelling of the same lobe."""
    h, w = _sphere_dirs(3000, 600)
    vh = h @ v
    l = 2 * vh[:, None] * h - v
    ok = (vh > 0) & (l[:, 2] > 0)
    nl = np.where(ok, l[:, 2], 1.0)
    tan2 = lambda c: (1 - c * c) / (c * c)   # noqa: E731
    D = 1 / (np.pi * alpha ** 2 * h[:, 2] ** 4 * (1 + tan2(h[:, 2]) / alpha ** 2) ** 2)
    G1 = lambda c: 2 / (1 + np.sqrt(1 + alpha ** 2 * tan2(c)))   # noqa: E731
    f = D * G1(nl) * G1(v[2]) / (4 * nl * v[2])
    return float(np.sum(np.where(ok, f * nl * 4 * vh, 0.0) * w))


@pytest.mark.parametrize("alpha", [0.1, 0.4, 0.8])
def test_energy_with_unit_fresnel(alpha):
    # directional albedo of f_s with F0 = 1 (white furnace, single scattering): at most
    # 1, and equal to the half-vector integral of the textbook formulas
    v = np.array([np.sin(0.5), 0.0, np.cos(0.5)])
    l, w = _sphere_dirs(1500, 600)
    h = l + v
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    term = ggx_specular(l[:, 2].astype(np.float32), np.float32(v[2]), (h[:, 2]).astype(np.float32),
                        (h @ v).astype(np.float32), alpha, 1.0)
    albedo = float(np.sum(term / np.pi * w))   # ggx_specular is pi f_s (n.l)
    assert albedo <= 1.0 + 2e-3
    assert albedo == pytest.approx(_albedo_half_vector(alpha, v), abs=5e-3)
    if alpha <= 0.1:
        assert albedo > 0.97   # smooth facets lose almost nothing to masking


def test_known_angles():
    # n = l = v: D = 1 / (pi a^2), G1 = 1, F = F0 -> pi f_s (n.l) = F0 / (4 a^2)
    a, f0 = 0.25, 0.05
    one = np.float32(1.0)
    assert float(ggx_specular(one, one, one, one, a, f0)) == pytest.approx(f0 / (4 * a * a), rel=1e-5)
    # l at 60 deg from n = v: h at 30 deg; tan-form Smith, Schlick at v.h = cos 30
    tl, th = np.radians(60.0), np.radians(30.0)
    D = a * a / (np.pi * np.cos(th) ** 4 * (a * a + np.tan(th) ** 2) ** 2)
    G1l = 2 / (1 + np.sqrt(1 + a * a * np.tan(tl) ** 2))
    F = f0 + (1 - f0) * (1 - np.cos(th)) ** 5
    want = np.pi * F * G1l * 1.0 * D / (4 * np.cos(tl) * 1.0) * np.cos(tl)
    got = ggx_specular(np.float32(np.cos(tl)), one, np.float32(np.cos(th)),
                       np.float32(np.cos(th)), a, f0)
    assert float(got) == pytest.approx(want, rel=1e-4)


def test_render_matches_per_pixel_formula():
    surf = ps.make_surface("semisphere", size=32)
    lay = ps.layout("30x4+60x4")
    a, f0 = 0.35, 0.2
    sc = ps.render(surf, lay, model="ggx", roughness=a, f0=f0, shadows=False, rho_s=0.7,
                   rho_d=0.5)
    n = surf.normals.reshape(-1, 3).astype(np.float64)
    m = surf.object_mask.ravel()
    v = np.array([0, 0, 1.0])
    for i, l in enumerate(lay.directions):
        h = (l + v) / np.linalg.norm(l + v)
        nl, nv, nh = n @ l, n @ v, n @ h
        tan2 = lambda c: (1 - c * c) / (c * c)   # noqa: E731
        D = a * a / (np.pi * nh ** 4 * (a * a + tan2(nh)) ** 2)
        G = 2 / (1 + np.sqrt(1 + a * a * tan2(nl))) * 2 / (1 + np.sqrt(1 + a * a * tan2(nv)))
        F = f0 + (1 - f0) * (1 - h @ v) ** 5
        want = np.where(nl > 0, 0.5 * nl + 0.7 * np.pi * F * G * D / (4 * nv), 0.0)
        got = sc.images[i].ravel()
        np.testing.assert_allclose(got[m], want[m], rtol=2e-3, atol=2e-5)


def test_render_ggx_bad_options():
    surf = ps.make_surface("semisphere", size=16)
    with pytest.raises(PsbenchError, match="roughness"):
        ps.render(surf, "45x4", model="ggx", roughness=0)
    with pytest.raises(PsbenchError, match="f0"):
        ps.render(surf, "45x4", model="ggx", f0=1.5)
    with pytest.raises(PsbenchError, match="bounces"):
        ps.render(surf, "45x4", model="ggx", bounces=1)
