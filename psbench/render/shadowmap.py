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

from . import _shadowmap_kernel as _k
from .._shared.checks import PsbenchError
from .._shared.deprecation import renamed_args

__all__ = ["shadow_map", "point_shadow_map", "light_directions"]

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


@renamed_args(renamed={"mask": "object_mask"})
def shadow_map(height, directions, *, object_mask=None, bias=0.5, background=None,
               oversample=2):
    """Cast-shadow maps of a height field for distant lights.

    Parameters
    ----------
    height : (H, W) array_like
        Heights in pixel units (z up, towards the camera). Non-finite heights are
        treated like pixels outside ``object_mask``.
    directions : (k, 3) or (3,) array_like, or Layout
        Unit vectors from the surface towards each light (normalised here),
        z >= 0. Light power does not matter.
    object_mask : (H, W) bool, optional
        Object region. Outside it heights are replaced by ``background`` (so they
        cast no shadow above that level) and the result is False (points outside
        the object receive no shadow). None: every pixel is part of the surface.
    bias : float, default 0.5
        Tolerance in pixel-height units: an occluder must rise more than ``bias``
        above the light ray. It suppresses self-shadow acne on noisy heights
        (e.g. heights integrated from estimated normals). 0 gives the exact test.
    background : float, optional
        Height given to pixels outside ``object_mask``; default the lowest height
        inside it.
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
    d = light_directions(directions)
    _check_oversample(oversample)
    h, inside, bias = _prepare(height, object_mask, bias, background)
    H, W = np.shape(height)
    out = np.zeros((d.shape[0], H, W), dtype=bool)
    if h is None:
        return out
    hmin, hmax = float(h.min()), float(h.max())
    # a one-pixel ring of "nothing" that BORDER_REPLICATE extends to infinity: samples
    # between the last pixel and the ring fade to the floor, so nothing exists
    # outside [0, W-1] x [0, H-1] (cv2's BORDER_CONSTANT is unreliable for samples a
    # hair outside the source)
    hpad = cv2.copyMakeBorder(h, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=float(_FLOOR))
    hb = h + np.float32(bias)
    work = {}  # buffers reused across lights (fresh large temporaries cost page faults)
    for i, (dx, dy, dz) in enumerate(d):
        rxy = float(np.hypot(dx, dy))
        if rxy < 1e-12:
            continue  # zenith 0: no cast shadows
        t = dz / rxy
        rise = hmax - hmin - bias
        if rise <= 0 or rise < 1e-3 * t:
            continue  # no occluder can rise above the ray within reach of any point
        _one(h, hb, hpad, dx / rxy, dy / rxy, t, int(oversample), out[i], work)
    if inside is not None:
        out &= inside[None]
    return out


def _check_oversample(oversample):
    if isinstance(oversample, (bool, np.bool_)) or not isinstance(oversample, (int, np.integer)) \
            or not 1 <= int(oversample) <= 4:
        raise PsbenchError(f"oversample must be an integer in 1..4, got {oversample!r}")


def _prepare(height, object_mask, bias, background):
    """Validate; return (float32 heights with the background applied or None when no
    pixel is inside, inside mask or None when every pixel is inside, bias)."""
    h = np.asarray(height)
    if h.ndim != 2 or not np.issubdtype(h.dtype, np.number) or h.dtype == bool:
        raise PsbenchError(f"height must be a numeric (H, W) array, got shape {h.shape} dtype {h.dtype}")
    H, W = h.shape
    if H < 1 or W < 1:
        raise PsbenchError(f"height must not be empty, got shape {h.shape}")
    try:
        bias = float(bias)
    except (TypeError, ValueError):
        raise PsbenchError(f"bias must be a number >= 0 (pixel-height units), got {bias!r}") from None
    if not np.isfinite(bias) or bias < 0:
        raise PsbenchError(f"bias must be a finite number >= 0 (pixel-height units), got {bias}")
    h = h.astype(np.float32)
    inside = np.isfinite(h)
    if object_mask is not None:
        m = np.asarray(object_mask)
        if m.shape != (H, W):
            raise PsbenchError(f"object_mask must have shape {(H, W)}, got {m.shape}")
        inside &= m.astype(bool)
    if not inside.any():
        return None, inside, bias
    if inside.all():
        return h, None, bias
    if background is None:
        bg = float(h[inside].min())
    else:
        try:
            bg = float(background)
        except (TypeError, ValueError):
            bg = float("nan")
        if not np.isfinite(bg):
            raise PsbenchError(f"background must be a finite number, got {background!r}")
    return np.where(inside, h, np.float32(bg)).astype(np.float32), inside, bias


def _buffer(work, name, shape, dtype):
    """A C-contiguous array of ``shape`` carved from a reusable flat buffer."""
    n = int(np.prod(shape))
    buf = work.get((name, dtype))
    if buf is None or buf.size < n:
        buf = work[(name, dtype)] = np.empty(n, dtype=dtype)
    return buf[:n].reshape(shape)


def _one(h, hb, hpad, ux, uy, t, over, out, work):
    """Write into ``out`` the (H, W) shadow map of one light: horizontal unit (ux, uy)
    in the x-right, y-up frame, rise t per pixel; ``over`` working columns per pixel
    across rays; ``work`` holds reusable buffers."""
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
    g = _buffer(work, "g", (L + 1, nq), dtype)
    cv2.warpAffine(src, fwd, (nq, L + 1), dst=g,
                   flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)
    # lift to the common reference, then the running max towards +rho (compiled)
    _k.lift_running_max(g, (T * (np.arange(L + 1, dtype=np.float64) - 1.0)).astype(dtype))
    # horizon of p = running max at working row rho(p), i.e. up to rho(p) - 1
    horizon = _buffer(work, "horizon", (H, W), dtype)
    cv2.warpAffine(g, back, (W, H), dst=horizon,
                   flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REPLICATE)
    # g(p) = h(p) + T rho(p), rho affine in (c, r): occluded where the horizon is above
    rowpart = (T * (back[1, 1] * np.arange(H) + back[1, 2])).astype(dtype)
    colpart = (T * (back[1, 0] * np.arange(W))).astype(dtype)
    _k.above(horizon, hb, rowpart, colpart, out)


@renamed_args(renamed={"mask": "object_mask"})
def point_shadow_map(height, positions, *, object_mask=None, bias=0.5, background=None,
                     oversample=2):
    """Cast-shadow maps of a height field for near point lights.

    Parameters
    ----------
    height : (H, W) array_like
        Heights in pixel units.
    positions : (k, 3) or (3,) array_like
        Light positions in pixel units: origin at the image centre on the height
        datum, x right, y up, z up (psbench's frame).
    object_mask, bias, background
        As in :func:`shadow_map`.
    oversample : int, default 2
        Samples per pixel along the radius and along the arc at the farthest
        image point (1..4). 2 agrees with a ray march on >= 99.5 % of the pixels
        of a sharp pillar (1: >= 99.3 %) at about 4x the cost of 1.

    Returns
    -------
    shadow : (k, H, W) bool
        True where the segment from the point to the light passes more than
        ``bias`` below the (bilinear) height field.

    Notes
    -----
    A perspective shadow map: around the light's foot point F (its projection on
    the image plane), the rays from the surface to the light are radial lines.
    Seen from the light L, a point q hides p (further out on the same radial line)
    when its depression slope ``sigma(q) = (L_z - h(q) + bias) / |q - F|`` is smaller
    than ``(L_z - h(p)) / |p - F|``. The height map is resampled on a polar grid
    around F (``cv2.remap``, bilinear, angle chunks), a running minimum of sigma
    runs outwards, and it is sampled back one radial step nearer the light.
    Radial samples do not fall on pixel centres, so unlike :func:`shadow_map` the
    edges of sharp occluders are resolved to about a radial step.
    """
    h, inside, bias = _prepare(height, object_mask, bias, background)
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim == 1:
        pos = pos[None, :]
    if pos.ndim != 2 or pos.shape[1] != 3 or not np.isfinite(pos).all():
        raise PsbenchError(f"positions must be a finite (k, 3) array, got shape {np.shape(positions)}")
    _check_oversample(oversample)
    H, W = np.shape(height)
    out = np.zeros((pos.shape[0], H, W), dtype=bool)
    if h is None:
        return out
    hpad = cv2.copyMakeBorder(h, 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=float(_FLOOR))
    for i, L in enumerate(pos):
        out[i] = _one_point(h, hpad, L, float(bias), int(oversample))
    if inside is not None:
        out &= inside[None]
    return out


def _one_point(h, hpad, L, bias, over):
    H, W = h.shape
    c0, r0 = (W - 1) / 2.0, (H - 1) / 2.0
    fc, fr = L[0] + c0, r0 - L[1]  # foot point in (col, row)
    Lz = L[2]
    # polar extent of the image rectangle (grown by a pixel) seen from the foot
    xs = np.array([-1.0, W, W, -1.0]) - fc
    ys = np.array([-1.0, -1.0, H, H]) - fr
    rho_max = float(np.hypot(xs, ys).max())
    inside_rect = -1.0 <= fc <= W and -1.0 <= fr <= H
    if inside_rect:
        rho0, phi0, span = 0.0, -np.pi, 2 * np.pi
    else:
        dxr = min(max(fc, -1.0), float(W)) - fc
        dyr = min(max(fr, -1.0), float(H)) - fr
        rho0 = max(float(np.hypot(dxr, dyr)) - 2.0, 0.0)
        pc = np.arctan2(r0 - fr, c0 - fc)
        rel = (np.arctan2(ys, xs) - pc + np.pi) % (2 * np.pi) - np.pi
        phi0, span = pc + rel.min(), float(rel.max() - rel.min())
    rover = over  # radial samples per pixel
    n_rad = int(np.ceil((rho_max - rho0) * rover)) + 3
    n_ang = min(int(np.ceil(span * rho_max * over)) + 3, 32000)  # cv2.remap limit
    dphi = span / (n_ang - 3) if not inside_rect else span / (n_ang - 1)
    rho = (rho0 + np.arange(n_rad, dtype=np.float64) / rover).astype(np.float32)
    with np.errstate(divide="ignore"):
        inv_rho = (1.0 / rho)[:, None]
    sig = np.empty((n_rad, n_ang), dtype=np.float32)
    step = max(1, (1 << 21) // n_rad)
    top = np.float32(Lz + bias)
    for a in range(0, n_ang, step):
        phi = phi0 + dphi * (np.arange(a, min(n_ang, a + step), dtype=np.float64)
                             - (0.0 if inside_rect else 1.0))  # margin column if outside
        mx = rho[:, None] * np.cos(phi).astype(np.float32)[None, :]
        mx += np.float32(fc + 1.0)
        my = rho[:, None] * np.sin(phi).astype(np.float32)[None, :]
        my += np.float32(fr + 1.0)
        hs = cv2.remap(hpad, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        nothing = hs <= np.float32(_FLOOR * 0.5)
        np.subtract(top, hs, out=hs)
        hs *= inv_rho
        if rho[0] == 0:
            hs[0] = np.inf
        np.copyto(hs, np.float32(np.inf), where=nothing)
        sig[:, a:a + hs.shape[1]] = hs
    for r in range(1, n_rad):  # running minimum outwards
        np.minimum(sig[r], sig[r - 1], out=sig[r])
    if inside_rect:  # close the circle for interpolation across phi = +-pi
        sig = np.concatenate([sig, sig[:, :1]], axis=1)
    dx = (np.arange(W, dtype=np.float32) - np.float32(fc))[None, :]
    dy = (np.arange(H, dtype=np.float32) - np.float32(fr))[:, None]
    rp = np.sqrt(dx * dx + dy * dy)
    ph = np.arctan2(np.broadcast_to(dy, (H, W)), np.broadcast_to(dx, (H, W)))
    if inside_rect:
        ja = (ph - np.float32(phi0)) / np.float32(dphi)
    else:
        ph -= np.float32(phi0)
        ph += np.float32(np.pi)
        np.remainder(ph, np.float32(2 * np.pi), out=ph)
        ph -= np.float32(np.pi)
        ja = ph / np.float32(dphi) + np.float32(1.0)
    jr = (rp - np.float32(rho0)) * np.float32(rover) - np.float32(1.0)  # one step nearer
    horizon = cv2.remap(sig, ja, jr, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    with np.errstate(divide="ignore", invalid="ignore"):
        own = (np.float32(Lz) - h) / rp
    return (horizon < own) & (rp >= 1.0)
