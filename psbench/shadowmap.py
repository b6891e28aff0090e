"""Cast shadows of distant lights on a height field (thesis Section 5.2.2).

:func:`shadow_map` is used twice in psbench: by :func:`psbench.render.render` to
put cast shadows into synthetic images, and by the solver's ``Sh`` mask on
heights integrated from *estimated* normals. It therefore has to be exact on
clean heights, robust to noisy ones (``bias``) and able to ignore the pixels
outside an object mask.

Definition
----------
Heights ``h`` are in pixel units, the frame is x right, y up (y = -row), lights
are orthographic (directional). For a light with unit direction
``d = (dx, dy, dz)`` let ``u`` be the unit horizontal direction towards the light
and ``t = dz / |(dx, dy)|`` the rise of the light ray per pixel of horizontal
travel. A point ``p`` is in cast shadow when some point of the height field
further along the ray rises above the ray by more than ``bias``::

    max_{s > 0} [ h(p + s u) - t s ]  >  h(p) + bias

(heights between pixels are bilinear). A light at zenith 0 never casts
shadows. Self shadow (``s.n <= 0``) is not this function's job, although a
self-shadowed point is usually also reported as occluded.

Algorithm (horizon sweep along sheared rays, O(H W) per light)
----------------------------------------------------------------
Take the image axis closest to the light's horizontal direction as the march
axis (rows or columns, flipped so the light lies before index 0) and shear the
height map so that every ray towards the light becomes one column of a working
grid (``cv2.warpAffine``; the march coordinate stays on whole pixels, so only
the across-ray coordinate is interpolated, linearly). There
``g = h + T * rho`` (rho: march index, T: ray rise per step) is the height
lifted to a common reference along the ray; the running maximum of ``g`` from
the light's side is the horizon. It is sampled back one march step nearer the
light (so it covers only points strictly beyond ``p``; linear across rays) and
compared with ``g(p)`` computed from the *original* heights at the original
pixel. Interpolating the continuous horizon, rather than warping a boolean map,
keeps shadow edges sub-pixel accurate: against a brute-force ray march with
bilinear heights the maps agree on more than 99.5 % of the pixels (exactly for
lights along an image axis).
"""
from __future__ import annotations

import cv2
import numpy as np

from ._checks import PsbenchError

__all__ = ["shadow_map", "light_directions"]

#: value given to rotated samples outside the image: "nothing there"
_FLOOR = np.float32(-1e30)


def light_directions(directions, name="directions"):
    """Return unit light directions as a float64 (k, 3) array.

    Accepts a :class:`psbench.lights.Layout`, a (k, 3) or (3,) array. Directions
    pointing below the horizon (z < 0) are refused.
    """
    d = getattr(directions, "directions", directions)
    d = np.asarray(d, dtype=np.float64)
    if d.ndim == 1:
        d = d[None, :]
    if d.ndim != 2 or d.shape[1] != 3:
        raise PsbenchError(f"{name} must have shape (k, 3) or (3,), got {np.shape(d)}")
    if not np.isfinite(d).all():
        raise PsbenchError(f"{name} holds NaN/inf values")
    norm = np.linalg.norm(d, axis=1)
    if (norm < 1e-12).any():
        raise PsbenchError(f"{name}: direction(s) {np.flatnonzero(norm < 1e-12).tolist()} are zero vectors")
    d = d / norm[:, None]
    below = np.flatnonzero(d[:, 2] < -1e-12)
    if below.size:
        raise PsbenchError(
            f"{name}: direction(s) {below.tolist()} point below the horizon (z < 0); "
            "light directions go from the surface towards the light, z >= 0")
    return d


def shadow_map(height, directions, *, mask=None, bias=0.5, background=None, oversample=2):
    """Cast-shadow maps of a height field for distant lights.

    Parameters
    ----------
    height : (H, W) array_like
        Heights in pixel units (z up, towards the camera). Non-finite heights are
        treated like pixels outside ``mask``.
    directions : (k, 3) or (3,) array_like, or Layout
        Unit vectors from the surface towards each light (normalised here),
        z >= 0. Light power does not matter.
    mask : (H, W) bool, optional
        Object mask. Outside it heights are replaced by ``background`` (so they
        cast no shadow above that level) and the result is False (points outside
        the object receive no shadow). None: every pixel is part of the surface.
    bias : float, default 0.5
        Tolerance in pixel-height units: an occluder must rise more than ``bias``
        above the light ray. It suppresses self-shadow acne on noisy heights
        (e.g. heights integrated from estimated normals). 0 gives the exact test.
    background : float, optional
        Height given to pixels outside ``mask``; default the lowest height inside
        the mask.
    oversample : int, default 2
        Working-grid samples per pixel across the rays (1..4). 2 resolves the shadow
        edges of sharp occluders (steps, pillars) better than 1 (agreement with a
        ray march 99.76 % vs 99.54 % of pixels on a pillar) at about 1.7x the
        time; 1 is enough for smooth or noisy heights.

    Returns
    -------
    shadow : (k, H, W) bool
        True where the point is occluded from light i by the height field.

    Notes
    -----
    Beyond the image border there is nothing: rays leaving the image are not
    occluded. See the module docstring for the definition and the algorithm.
    """
    h = np.asarray(height)
    if h.ndim != 2 or not np.issubdtype(h.dtype, np.number) or h.dtype == bool:
        raise PsbenchError(f"height must be a numeric (H, W) array, got shape {h.shape} dtype {h.dtype}")
    H, W = h.shape
    if H < 1 or W < 1:
        raise PsbenchError(f"height must not be empty, got shape {h.shape}")
    d = light_directions(directions)
    bias = float(bias)
    if not np.isfinite(bias) or bias < 0:
        raise PsbenchError(f"bias must be a finite number >= 0 (pixel-height units), got {bias}")
    if isinstance(oversample, (bool, np.bool_)) or not isinstance(oversample, (int, np.integer)) \
            or not 1 <= int(oversample) <= 4:
        raise PsbenchError(f"oversample must be an integer in 1..4, got {oversample!r}")
    h = h.astype(np.float32)
    finite = np.isfinite(h)
    inside = finite
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != (H, W):
            raise PsbenchError(f"mask must have shape {(H, W)}, got {m.shape}")
        inside = finite & m.astype(bool)
    out = np.zeros((d.shape[0], H, W), dtype=bool)
    if not inside.any():
        return out
    if not inside.all():
        if background is None:
            bg = float(h[inside].min())
        else:
            bg = float(background)
            if not np.isfinite(bg):
                raise PsbenchError(f"background must be finite, got {background}")
        h = np.where(inside, h, np.float32(bg)).astype(np.float32)
    hmin, hmax = float(h.min()), float(h.max())
    # a one-pixel ring of "nothing" that BORDER_REPLICATE extends to infinity: samples
    # between the last pixel and the ring fade to the floor, so nothing exists
    # outside [0, W-1] x [0, H-1] (cv2's BORDER_CONSTANT is unreliable for samples a
    # hair outside the source)
    hpad = cv2.copyMakeBorder(h, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=float(_FLOOR))
    hb = h + np.float32(bias)
    for i, (dx, dy, dz) in enumerate(d):
        rxy = float(np.hypot(dx, dy))
        if rxy < 1e-12:
            continue  # zenith 0: no cast shadows
        t = dz / rxy
        rise = hmax - hmin - bias
        if rise <= 0 or rise < 1e-3 * t:
            continue  # no occluder can rise above the ray within reach of any point
        out[i] = _one(h, hb, hpad, dx / rxy, dy / rxy, t, int(oversample))
    if mask is not None or not finite.all():
        out &= inside[None]
    return out


def _one(h, hb, hpad, ux, uy, t, over=1):
    """Shadow map (H, W) bool for one light: horizontal unit (ux, uy) in the x-right,
    y-up frame, rise t per pixel; ``over`` working columns per pixel across rays."""
    H, W = h.shape
    a, b = ux, -uy  # towards the light in (col, row) units
    rows = abs(b) >= abs(a)
    if rows:  # march along rows; k: column change per step towards the light
        L, La, k, T = H, W, a / abs(b), t / abs(b)
    else:
        L, La, k, T = W, H, b / abs(a), t / abs(a)
    lo, hi = min(0.0, k * (L - 1)), max(0.0, k * (L - 1))
    qmin = float(np.floor(lo)) - 1.0
    nq = int(np.ceil((hi + La - qmin) * over)) + 1
    s = 1.0 / over
    # F: working (j, rho) -> source (c, r); the ray through q = qmin + j/over is
    # (across) = q - k rho, and rho = 0 is the image edge facing the light.
    if rows:
        F = np.array([[s, -k, qmin], [0.0, 1.0, 0.0]] if b < 0 else
                     [[s, -k, qmin], [0.0, -1.0, H - 1.0]])
    else:
        F = np.array([[0.0, 1.0, 0.0], [s, -k, qmin]] if a < 0 else
                     [[0.0, -1.0, W - 1.0], [s, -k, qmin]])
    back = cv2.invertAffineTransform(F)  # source (c, r) -> working (j, rho)
    # working row w = rho + 1 (row 0 lies outside the image: the exclusive start),
    # +1 for the floor ring around the source
    fwd = F.copy()
    fwd[:, 2] += 1.0 - F[:, 1]
    big = T * (L + 1) > 5e4  # g = h + T rho loses float32 precision for steep lights
    dtype = np.float64 if big else np.float32
    src = hpad.astype(dtype) if big else hpad
    g = cv2.warpAffine(src, fwd, (nq, L + 1), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                       borderMode=cv2.BORDER_REPLICATE)
    g += (T * (np.arange(L + 1, dtype=np.float64) - 1.0)).astype(dtype)[:, None]
    for w in range(1, L + 1):  # running max towards +rho (row loop: ~5x faster
        np.maximum(g[w], g[w - 1], out=g[w])  # than np.maximum.accumulate(axis=0))
    # horizon of p = running max at working row rho(p), i.e. up to rho(p) - 1
    horizon = cv2.warpAffine(g, back, (W, H), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                             borderMode=cv2.BORDER_REPLICATE)
    # g(p) = h(p) + T rho(p), rho affine in (c, r)
    rowpart = (T * (back[1, 1] * np.arange(H) + back[1, 2])).astype(dtype)
    colpart = (T * (back[1, 0] * np.arange(W))).astype(dtype)
    thr = hb.astype(dtype, copy=False) + rowpart[:, None]
    thr += colpart[None, :]
    return horizon > thr
