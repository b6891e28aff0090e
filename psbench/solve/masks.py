"""Image masks (Th, NL) and normal masks (SS, Re, CS, Hi, Sh) of the unified PS (Ch. 3).

Every function returns **validity** (True = observation used, the thesis's F = 1) as
a bool array of the images' shape. They work on any pixel layout: ``images`` is
(k, *P) and ``b`` (rho * n) is (*P, 3), so (k, H, W) with (H, W, 3) and the flat
(k, N) with (N, 3) both work. Ranges (``lo``, ``rng``) are arrays broadcastable to
``images`` -- (k, 1) or (k, 1, 1) per image, or (1, N) per pixel -- computed once by
:func:`ranges`.

Decisions (psbench):

* **Th offset (Eq. 3.2).** The thesis writes ``i < k_low (i_max - i_min)`` and
  ``i > k_up (i_max - i_min)``: the bounds are fractions of the range, not offset by
  i_min. psbench keeps that literal rule by default (``th_offset=False``);
  ``th_offset=True`` offsets both bounds by i_min (``i < i_min + k_low (i_max -
  i_min)``), which is invariant to an added constant (ambient light, dark level).
  Noiseless renders have i_min = 0 and both give the same masks; with noise the
  image minimum is a negative noise extreme (about -4 sigma), which drags both
  offset bounds down: shadows escape the lower bound and lit diffuse observations
  exceed the upper one. On the five test surfaces (45x8, TS, 256 px) Th's mean NE
  with offset / literal / None: 5 % noise 18.1 / 10.1 / 10.1 deg, 10 % noise
  28.2 / 17.3 / 11.9 deg, 20 % noise 36.3 / 19.7 / 16.4 deg.
* **Range scope** (``th_scope``): "image" (thesis: min/max of each whole image),
  "object" (min/max over the object mask), "robust" (1st-99th percentile over the
  object, so one specular spot does not set the range), "pixel" (albedo-invariant:
  the lower Th bound, Hi and CS use the pixel's brightest observation over the k
  images as range with i_min = 0; the upper Th bound keeps the "robust" image range,
  because k_up = 0.35 of a pixel's own maximum would mask most diffuse
  observations, and highlights are additive rather than scaled by the diffuse
  albedo).
* **NL (Eqs. 3.3-3.6)**: ``a`` spans the null space of S^T (S is 4x3), normalised to
  unit L2 norm with a_1 >= 0; intensities are divided by the mean dynamic range of
  the four images so that the Lambertian error ``(a I / R)^2`` and t_NL are
  scale-free. A failing quadruple masks its **darkest** observation when that one
  is below the Th lower bound (i_min + k_low * range: a shadow), else its
  **brightest** (a highlight). With Re in the combination (Barsky's NL-Re) the
  observation(s) of the failing quadruple flagged by Re on the first least-squares
  normals are masked instead of the brightest, when Re flags any.
* **SS / Re (Eqs. 3.7/3.8)** print the masked and kept cases inverted; psbench masks
  where s.n <= 0 (SS) and where angle(n, bisector(d, v)) < t_Re (Re, degrees).
* **Sh** masks cast shadows (shadow map of the integrated heights seen from every
  light) and self shadows (s.n <= 0): Section 3.3.2.5 says Sh "works on both".
"""
from __future__ import annotations

import numpy as np

from .._checks import PsbenchError
from . import kernel

__all__ = ["SCOPES", "ranges", "th", "nl", "nl_vector", "ss", "re", "cs", "hi", "sh",
           "sh_maps"]

SCOPES = ("image", "object", "robust", "pixel")


def _lambert_flat(b, S):
    """s_i . b for b (*P, 3) -> (k, *P) float32."""
    P = b.shape[:-1]
    S = np.asarray(S, dtype=np.float32)
    return (S @ b.reshape(-1, 3).T).reshape((S.shape[0],) + P)


def ranges(images, *, scope="image", object_mask=None, offset=False):
    """Dynamic ranges used by Th, Hi, CS (and NL scaling).

    Parameters
    ----------
    images : (k, H, W) float32
    scope : {"image", "object", "robust", "pixel"}
    object_mask : (H, W) bool, optional
    offset : bool
        Offset the Th bounds by i_min (True) or not (False, literal Eq. 3.2, default).

    Returns
    -------
    dict with
        ``lo`` (k, 1, 1) or (1, H, W): i_min used as offset for Th (0 if not offset),
        ``rng`` (k, 1, 1) or (1, H, W): range for the lower Th bound, Hi and CS,
        ``lo_up``, ``rng_up`` (k, 1, 1): offset and range for the upper Th bound,
        ``scale`` float: mean image range (NL scaling, > 0),
        ``dead`` (k, 1, 1) bool: images with zero range; Th, Hi and CS never mask
        them (a constant image carries no range to be a fraction of).
    """
    k = images.shape[0]
    flat = images.reshape(k, -1)
    m = None if object_mask is None or object_mask.all() else object_mask.reshape(-1)
    if scope == "image":
        imin, imax = flat.min(axis=1), flat.max(axis=1)
    elif scope == "object":
        sel = flat if m is None else flat[:, m]
        imin, imax = _minmax(sel)
    elif scope in ("robust", "pixel"):
        sel = flat if m is None else flat[:, m]
        imin, imax = _percentiles(sel)
    else:
        raise PsbenchError(f"th_scope={scope!r} is not known; valid choices: {', '.join(SCOPES)}")
    imin = imin.astype(np.float32)
    rng_img = np.maximum(imax.astype(np.float32) - imin, 0.0)
    lo_img = imin if offset else np.zeros_like(imin)
    out = {"lo_up": lo_img.reshape(k, 1, 1), "rng_up": rng_img.reshape(k, 1, 1)}
    if scope == "pixel":
        pmax = images.max(axis=0, keepdims=True)
        out["lo"] = np.zeros((1, 1, 1), dtype=np.float32)
        out["rng"] = pmax
    else:
        out["lo"], out["rng"] = out["lo_up"], out["rng_up"]
    scale = float(rng_img.mean())
    out["scale"] = scale if scale > 0 else 1.0
    out["dead"] = (rng_img <= 0).reshape(k, 1, 1)  # zero-range images: masks keep them
    return out


def _minmax(sel):
    if sel.shape[1] == 0:
        z = np.zeros(sel.shape[0], dtype=np.float32)
        return z, z
    return sel.min(axis=1), sel.max(axis=1)


def _percentiles(sel, q=(1.0, 99.0), max_samples=1 << 16):
    """1st and 99th percentiles per image (on a regular subsample for speed)."""
    if sel.shape[1] == 0:
        z = np.zeros(sel.shape[0], dtype=np.float32)
        return z, z
    step = max(1, sel.shape[1] // max_samples)
    p = np.percentile(sel[:, ::step], q, axis=1)
    return p[0], p[1]


def th(images, lo, rng, k_low, k_up, *, lo_up=None, rng_up=None, out=None):
    """Threshold mask (Eq. 3.2): valid where lo + k_low rng <= i <= lo_up + k_up rng_up.

    Parameters
    ----------
    images : (k, *P) float32
    lo, rng : arrays broadcastable to images
        Offset and range of the lower bound (and of the upper bound unless ``lo_up``,
        ``rng_up`` are given).

    Returns
    -------
    valid : (k, *P) bool
    """
    lo_up = lo if lo_up is None else lo_up
    rng_up = rng if rng_up is None else rng_up
    low = (lo + np.float32(k_low) * rng).astype(np.float32)
    up = (lo_up + np.float32(k_up) * rng_up).astype(np.float32)
    valid = np.greater_equal(images, low, out=out)
    valid &= images <= up
    return valid


def nl_vector(S):
    """The vector a with a S = 0 (Eq. 3.3) for 4 lights, unit L2 norm, a[0] >= 0."""
    S = np.asarray(S, dtype=np.float64)
    if S.shape != (4, 3):
        raise PsbenchError(f"NL needs exactly 4 lights (S of shape (4, 3)), got {S.shape}")
    _, _, vt = np.linalg.svd(S.T)
    a = vt[-1]
    a = a / np.linalg.norm(a)
    return a if a[0] >= 0 else -a


def nl(images, S, t_nl, *, scale=1.0, shadow_level=None, prefer=None):
    """Non-Lambert quadruple mask (Eqs. 3.3-3.6) for exactly four images.

    Parameters
    ----------
    images : (4, *P) float32
    S : (4, 3)
    t_nl : float
        Threshold on ``(a I / scale)^2``.
    scale : float
        Intensity scale (mean dynamic range), makes t_NL scale-free.
    shadow_level : array broadcastable to images, optional
        Observations below it count as shadows (default: 0, i.e. never).
    prefer : (4, *P) bool, optional
        Observations to mask in failing quadruples instead of the brightest (e.g. the
        Re flags for NL-Re); used where any of them is set and the darkest is not a
        shadow.

    Returns
    -------
    valid : (4, *P) bool
        False at one observation (or the ``prefer`` ones) of each failing quadruple.
    """
    k = images.shape[0]
    if k != 4:
        raise PsbenchError(f"NL needs exactly 4 images, got {k}")
    a = (nl_vector(S) / scale).astype(np.float32)
    e = np.tensordot(a, images, axes=1)
    fail = e * e > np.float32(t_nl)
    valid = np.ones(images.shape, dtype=bool)
    if not fail.any():
        return valid
    shape = images.shape
    flat = images.reshape(4, -1)
    f = fail.reshape(-1)
    cols = np.flatnonzero(f)
    sub = flat[:, cols]
    pick = sub.argmax(axis=0)
    is_shadow = np.zeros(cols.size, dtype=bool)
    if shadow_level is not None:
        lvl = np.broadcast_to(shadow_level, shape).reshape(4, -1)[:, cols]
        dark = sub.argmin(axis=0)
        ar = np.arange(cols.size)
        is_shadow = sub[dark, ar] < lvl[dark, ar]
        pick = np.where(is_shadow, dark, pick)
    vflat = valid.reshape(4, -1)
    vflat[pick, cols] = False
    if prefer is not None:
        pf = np.asarray(prefer, dtype=bool).reshape(4, -1)[:, cols]
        use = ~is_shadow & pf.any(axis=0)
        if use.any():
            vflat[:, cols[use]] = ~pf[:, use]
    return valid


def ss(b, S):
    """Self-shadow mask (Eq. 3.7, corrected): valid where s . n > 0. b: (*P, 3)."""
    return _lambert_flat(b, S) > 0


def bisectors(directions):
    """Unit bisectors of each light direction and the view vector v = (0, 0, 1), (k, 3)."""
    d = np.asarray(directions, dtype=np.float64)
    h = d + np.array([0.0, 0.0, 1.0])
    return h / np.linalg.norm(h, axis=1, keepdims=True)


def re(normals, directions, t_re):
    """Reflection mask (Eq. 3.8, corrected): valid where angle(n, h_i) >= t_Re.

    Parameters
    ----------
    normals : (*P, 3) unit normals
    directions : (k, 3) light directions
    t_re : float or (k,) degrees

    Returns
    -------
    valid : (k, *P) bool
    """
    H = bisectors(directions)
    k = H.shape[0]
    c = np.cos(np.radians(np.broadcast_to(np.asarray(t_re, dtype=float), (k,))))
    P = normals.shape[:-1]
    cosang = (H.astype(np.float32) @ normals.reshape(-1, 3).T).reshape((k,) + P)
    return cosang <= c.astype(np.float32).reshape((k,) + (1,) * len(P))


def residual_lambert(images, b, S):
    """Signed residuals i - rho s.n, (k, *P) float32 (b is (*P, 3))."""
    return images - _lambert_flat(b, S)


def cs(images, b, S, rng, k_cs, *, resid=None):
    """Cast-shadow mask (Eq. 3.9): valid where i - rho s.n >= k_CS * range."""
    r = residual_lambert(images, b, S) if resid is None else resid
    return r >= np.float32(k_cs) * rng


def hi(images, b, S, rng, k_hi, *, resid=None):
    """Highlight mask (Eq. 3.10): valid where i - rho s.n <= k_Hi * range."""
    r = residual_lambert(images, b, S) if resid is None else resid
    return r <= np.float32(k_hi) * rng


def sh_maps(normals, directions, object_mask=None, *, bias=None, method="poisson"):
    """Cast-shadow maps of the heights integrated from ``normals``.

    Parameters
    ----------
    normals : (H, W, 3) float32
    directions : (k, 3)
    object_mask : (H, W) bool, optional

    Returns
    -------
    occluded : (k, H, W) bool
        True where light i is blocked by another part of the integrated surface.
    height : (H, W) float32
    """
    from ..integrate import integrate
    from ..shadowmap import shadow_map

    height = integrate(normals, object_mask, method=method)
    kw = {} if bias is None else {"bias": bias}
    occ = shadow_map(height, np.asarray(directions, dtype=np.float64), mask=object_mask, **kw)
    return np.asarray(occ, dtype=bool), height


def sh(normals, b, S, directions, object_mask=None, **kw):
    """Shadow mask (Section 3.3.2.5): valid where not cast-shadowed and s . n > 0.

    Returns
    -------
    valid : (k, H, W) bool
    height : (H, W) float32
    """
    occ, height = sh_maps(normals, directions, object_mask, **kw)
    valid = ss(b, S)
    valid &= ~occ
    return valid, height
