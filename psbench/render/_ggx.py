"""The GGX (Trowbridge-Reitz) microfacet lobe of ``render(..., model="ggx")``.

A specular lobe that none of psbench's solvers models (tsfit fits Torrance-Sparrow,
Eq. 2.14): the microfacet BRDF of Walter et al. (2007) with the GGX normal distribution,
the separable Smith masking-shadowing term and Schlick's Fresnel approximation::

    f_s(l, v) = F(v.h) G1(n.l) G1(n.v) D(n.h) / (4 (n.l) (n.v))
    D(n.h)  = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)
    G1(c)   = 2 c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2))
    F(v.h)  = F0 + (1 - F0) (1 - v.h)^5

with h = (l + v) / |l + v| and alpha the roughness (``roughness``, > 0). The image is

    I = mu [rho_d (n.l) + rho_s pi f_s(l, v) (n.l)]

the factor pi matching psbench's Lambert term rho_d (n.l), which drops the 1/pi of the
Lambertian BRDF rho_d / pi: with rho_s = 1 the lobe is the physical one relative to a
white Lambertian surface. At n = l = v the specular term is F0 / (4 alpha^2); the
directional albedo of f_s with F0 = 1 is at most 1 (energy conservation; the shortfall
at large alpha is the multiple scattering the Smith term leaves out). The pieces are
plain numpy functions on float32 planes, used light by light by
:class:`psbench.render._shading.Shader`.
"""
from __future__ import annotations

import numpy as np

__all__ = ["ggx_d", "smith_g1", "schlick", "ggx_specular"]

#: floor of n.v: a height field seen from above never has n.v <= 0, but a vertical
#: wall comes close; G1(n.v) / (n.v) stays finite there (limit 2 / alpha).
_NV_FLOOR = np.float32(1e-6)


def ggx_d(cos_nh, alpha):
    """GGX normal distribution D (1/sr) of (H, W) or scalar cos(n, h)."""
    a2 = np.float32(alpha) ** 2 if np.ndim(alpha) == 0 else np.square(alpha)
    c2 = np.square(cos_nh)
    den = c2 * (a2 - 1) + 1
    return a2 / (np.float32(np.pi) * den * den)


def smith_g1(cos, alpha):
    """Smith masking G1 of the GGX distribution for direction cosine(s) ``cos`` > 0."""
    a2 = np.float32(alpha) ** 2 if np.ndim(alpha) == 0 else np.square(alpha)
    c = np.asarray(cos, dtype=np.float32)
    return 2 * c / (c + np.sqrt(a2 + (1 - a2) * c * c))


def schlick(cos_vh, f0):
    """Schlick's Fresnel approximation F0 + (1 - F0)(1 - v.h)^5."""
    t = np.clip(1 - np.asarray(cos_vh, dtype=np.float32), 0, 1)
    t2 = t * t
    return f0 + (1 - f0) * (t2 * t2 * t)


def ggx_specular(nl, nv, nh, vh, alpha, f0, out=None):
    """pi f_s(l, v) (n.l) = pi F D G1(n.l) G1(n.v) / (4 n.v): the specular term of one
    light per unit rho_s and light power.

    Parameters
    ----------
    nl, nv, nh, vh : (H, W) float32 or float
        n.l, n.v, n.h and v.h (h the unit bisector of l and v). Where n.l <= 0 the
        term is 0 (the caller also sets it to 0 in shadow).
    alpha : float or (H, W) float32
        Roughness, > 0.
    f0 : float or (H, W) float32
        Fresnel reflectance at normal incidence, in [0, 1].
    out : (H, W) float32, optional
        Where to write the result.

    Returns
    -------
    (H, W) float32
    """
    nl = np.maximum(nl, 0)
    nv = np.maximum(nv, _NV_FLOOR)
    a2 = np.float32(alpha) ** 2 if np.ndim(alpha) == 0 else np.square(alpha)
    # G1(n.v) / (4 n.v) in the form that stays finite at grazing views
    gv = 0.5 / (nv + np.sqrt(a2 + (1 - a2) * nv * nv))
    val = np.float32(np.pi) * ggx_d(nh, alpha) * smith_g1(nl, alpha) * gv * schlick(vh, f0)
    val = np.asarray(val, dtype=np.float32)
    if out is None:
        return val
    np.copyto(out, val)
    return out
