"""Test surfaces: height maps with object masks and unit normals.

Every surface lives in the psbench frame (thesis 2.2): x to the right, y up
(``y = -row``), the camera at +z looking down -z, heights in **pixel units**.
Pixel (row ``r``, column ``c``) of an (H, W) map sits at
``x = c - (W - 1) / 2``, ``y = (H - 1) / 2 - r``. A surface ``z(x, y)`` has the
unit normal ``n ∝ (-dz/dx, -dz/dy, 1)``.

Named surfaces (:data:`SURFACES`), built by :func:`make_surface`:

``semisphere``
    A hemisphere of radius ``0.45 * size`` centred in the frame; the mask is
    its disc, the background (height 0) is not part of the object. Analytic
    normals.
``spheres``
    Five non-overlapping hemispheres of different radii standing on a flat
    plane (height 0). The plane is part of the mask, so the spheres cast
    shadows on it. Analytic normals.
``sombrero1``, ``sombrero2``, ``sombrero3``
    ``z = A sin(r/λ) / (r/λ)`` on ``[-7200, 7200]²`` (thesis Chapter 4) with
    peaks ``A = 1750, 3500, 7000``; one ``λ`` (:data:`SOMBRERO_LAMBDA`) for
    all three, chosen so that sombrero2's largest surface zenith is 66°
    (thesis Fig. 4.9). Mapped onto the size × size grid; heights scaled by
    ``size / 14400`` into pixel units. The mask is the whole square. Analytic
    normals. ``sombrero`` (Chapter 5) is sombrero2.
``mozart``
    A procedural bust in the spirit of the Mozart height map: head with nose,
    eye sockets, brows, lips and chin, a hair volume with wavy curls, neck and
    shoulders, standing on a background plane (height 0) that is part of the
    mask. Its sides are steep, so it casts shadows on the plane. Normals by
    central differences of the height.
``penny``
    A coin lying on a background plane (height 0, part of the mask): a disc
    with a vertical edge and a raised rim, a low-relief embossed bust in
    profile and a lettering-like ring of small bumps. Normals by central
    differences of the height.

User height maps: :func:`surface_from_height` and :func:`surface_from_file`.
The command ``psbench-surfaces`` (:func:`main`) writes preview PNGs.

All functions are pure (no caches, no global state) and vectorized.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._checks import PsbenchError, as_mask, choice
from ._fs import atomic_write

__all__ = ["Surface", "SURFACES", "SOMBRERO_LAMBDA", "SOMBRERO_PEAKS", "make_surface",
           "surface_from_height", "surface_from_file", "normals_from_height",
           "pixel_grid", "sombrero_lambda", "main"]

SURFACES = ("semisphere", "spheres", "sombrero", "sombrero1", "sombrero2", "sombrero3",
            "mozart", "penny")

#: Sombrero peaks (thesis units) of sombrero1, sombrero2, sombrero3.
SOMBRERO_PEAKS = {"sombrero1": 1750.0, "sombrero2": 3500.0, "sombrero3": 7000.0}
#: Half width of the sombrero domain [-7200, 7200]² in thesis units.
SOMBRERO_HALF = 7200.0

MIN_SIZE = 16


# --------------------------------------------------------------------------- Surface
@dataclass(frozen=True, eq=False)
class Surface:
    """A height field with its object mask and unit normals.

    Attributes
    ----------
    name : str
        Surface name.
    height : (H, W) float32
        Heights in pixel units (+z towards the camera). Outside the mask the
        height is the background the object sits on (0 for the named
        surfaces).
    mask : (H, W) bool
        Object mask: True where the surface is part of the object under test.
    normals : (H, W, 3) float32
        Unit normals ``(nx, ny, nz)`` in the psbench frame (x right, y up,
        camera at +z). Outside the mask they are ``(0, 0, 1)``.

    The arrays are stored read-only; copy them before modifying.
    """

    name: str
    height: np.ndarray
    mask: np.ndarray
    normals: np.ndarray

    def __post_init__(self):
        height = np.array(self.height, dtype=np.float32, copy=True)
        if height.ndim != 2:
            raise PsbenchError(f"height must have shape (H, W), got {height.shape}")
        mask = np.array(as_mask(self.mask, height.shape, "mask"), dtype=bool, copy=True)
        normals = np.array(self.normals, dtype=np.float32, copy=True)
        if normals.shape != height.shape + (3,):
            raise PsbenchError(
                f"normals must have shape {height.shape + (3,)}, got {normals.shape}")
        if not (np.isfinite(height).all() and np.isfinite(normals).all()):
            raise PsbenchError("height and normals must be finite")
        for arr in (height, mask, normals):
            arr.setflags(write=False)
        object.__setattr__(self, "name", str(self.name))
        object.__setattr__(self, "height", height)
        object.__setattr__(self, "mask", mask)
        object.__setattr__(self, "normals", normals)

    @property
    def shape(self):
        """(H, W) of the height map."""
        return self.height.shape

    @property
    def zenith(self):
        """(H, W) float32: surface zenith in degrees, the angle between the normal and +z."""
        nz = np.clip(self.normals[..., 2], -1.0, 1.0)
        return np.degrees(np.arccos(nz)).astype(np.float32)

    def __repr__(self):
        h = self.height[self.mask] if self.mask.any() else self.height
        return (f"Surface(name={self.name!r}, shape={self.shape}, "
                f"mask={int(self.mask.sum())} px, height=[{h.min():.3g}, {h.max():.3g}] px, "
                f"max zenith={float(self.zenith[self.mask].max()) if self.mask.any() else 0:.1f} deg)")


# --------------------------------------------------------------------------- helpers
def pixel_grid(shape):
    """Pixel-centre coordinates in the psbench frame.

    Parameters
    ----------
    shape : (H, W)

    Returns
    -------
    x : (1, W) float64
        ``c - (W - 1) / 2`` (x to the right).
    y : (H, 1) float64
        ``(H - 1) / 2 - r`` (y up). ``x`` and ``y`` broadcast to (H, W).
    """
    h, w = int(shape[0]), int(shape[1])
    x = (np.arange(w, dtype=np.float64) - (w - 1) / 2.0)[None, :]
    y = ((h - 1) / 2.0 - np.arange(h, dtype=np.float64))[:, None]
    return x, y


def _normals_from_slopes(p, q):
    """Unit normals from slopes p = dz/dx, q = dz/dy -> (H, W, 3) float32."""
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    p, q = np.broadcast_arrays(p, q)
    inv = 1.0 / np.sqrt(1.0 + p * p + q * q)
    out = np.empty(p.shape + (3,), dtype=np.float32)
    out[..., 0] = -p * inv
    out[..., 1] = -q * inv
    out[..., 2] = inv
    return out


def normals_from_height(height):
    """Unit normals of a height map by central differences (``np.gradient``).

    Parameters
    ----------
    height : (H, W) array_like
        Heights in pixel units, H, W >= 2.

    Returns
    -------
    normals : (H, W, 3) float32
        ``n ∝ (-dz/dx, -dz/dy, 1)`` with ``dz/dx = d/dcol`` and
        ``dz/dy = -d/drow`` (y up). One-sided differences on the border.
    """
    z = np.asarray(height, dtype=np.float64)
    d_row, d_col = np.gradient(z)
    return _normals_from_slopes(d_col, -d_row)


def _finish(name, height, mask, normals):
    """Build a Surface with normals (0, 0, 1) outside the mask."""
    normals = np.asarray(normals, dtype=np.float32)
    if not mask.all():
        normals = normals.copy()
        normals[~mask] = (0.0, 0.0, 1.0)
    return Surface(name=name, height=height.astype(np.float32), mask=mask, normals=normals)


def _check_size(size):
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)):
        raise PsbenchError(f"size must be an integer >= {MIN_SIZE}, got {size!r}")
    if size < MIN_SIZE:
        raise PsbenchError(f"size must be an integer >= {MIN_SIZE}, got {size}")
    return int(size)


def _smax(a, b, k):
    """Smooth maximum of a and b (log-sum-exp with sharpness k, in height units)."""
    m = np.maximum(a, b)
    return m + np.log(np.exp(k * (a - m)) + np.exp(k * (b - m))) / k


def _gauss(u, v, u0, v0, su, sv):
    """Separable axis-aligned Gaussian exp(-(du²/2su² + dv²/2sv²)) as an outer product."""
    return np.exp(-0.5 * ((v - v0) / sv) ** 2) * np.exp(-0.5 * ((u - u0) / su) ** 2)


def _dome(u, v, u0, v0, a, b, c, power=0.5):
    """Ellipsoid-like dome c * (1 - q)^power inside the ellipse q < 1, else 0."""
    q = ((v - v0) / b) ** 2 + ((u - u0) / a) ** 2
    return c * np.maximum(1.0 - q, 0.0) ** power


# --------------------------------------------------------------------------- sombrero
def _sinc_slope(u):
    """d/du [sin(u)/u]."""
    return (u * math.cos(u) - math.sin(u)) / (u * u)


def _sinc_curv(u):
    """d²/du² [sin(u)/u]."""
    return (-u * u * math.sin(u) - 2.0 * u * math.cos(u) + 2.0 * math.sin(u)) / u ** 3


def sombrero_lambda(max_zenith=66.0, peak=3500.0):
    """Solve for the sombrero length scale λ (thesis units).

    The sombrero ``z = A sin(r/λ)/(r/λ)`` has radial slope ``A/λ · f'(r/λ)``
    with ``f(u) = sin(u)/u``. Its steepest point is the first extremum of
    ``f'``, the root ``u* ≈ 2.0816`` of ``f''(u) = 0`` (found here by
    bisection on [1.5, 3]), where ``|f'(u*)| ≈ 0.43618``. Requiring the
    largest surface zenith of sombrero2 (``A = 3500``) to be 66° (thesis
    Fig. 4.9) gives::

        λ = A |f'(u*)| / tan(66°) ≈ 679.70

    With this λ the steepest ring (r = u* λ ≈ 1415) lies well inside the
    domain, and the maximal zeniths are ≈ 48.3° (sombrero1), 66.0°
    (sombrero2) and 77.4° (sombrero3).
    """
    lo, hi = 1.5, 3.0  # f'' changes sign once on this bracket
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if (_sinc_curv(lo) < 0) == (_sinc_curv(mid) < 0):
            lo = mid
        else:
            hi = mid
    u_star = 0.5 * (lo + hi)
    return peak * abs(_sinc_slope(u_star)) / math.tan(math.radians(max_zenith))


#: One λ (thesis units) for all three sombreros; see :func:`sombrero_lambda` (≈ 679.70).
SOMBRERO_LAMBDA = sombrero_lambda()


def _sombrero(name, size):
    peak = SOMBRERO_PEAKS[name]
    lam = SOMBRERO_LAMBDA
    scale = size / (2.0 * SOMBRERO_HALF)      # pixels per thesis unit
    x, y = pixel_grid((size, size))
    X, Y = x / scale, y / scale               # thesis units
    r = np.sqrt(X * X + Y * Y)
    u = r / lam
    z = peak * np.sinc(u / np.pi)             # np.sinc(t) = sin(pi t)/(pi t)
    # slope dz/dr = A/λ f'(u); f'(u) ~ -u/3 near 0
    small = u < 1e-4
    us = np.where(small, 1.0, u)
    fp = np.where(small, -u / 3.0, (us * np.cos(us) - np.sin(us)) / (us * us))
    dzdr = peak / lam * fp
    rs = np.where(r > 0, r, 1.0)
    p = np.where(r > 0, dzdr * X / rs, 0.0)   # dz/dx is scale invariant
    q = np.where(r > 0, dzdr * Y / rs, 0.0)
    mask = np.ones((size, size), dtype=bool)
    return Surface(name=name, height=(z * scale).astype(np.float32), mask=mask,
                   normals=_normals_from_slopes(p, q))


# --------------------------------------------------------------------------- spheres
def _semisphere(size):
    R = 0.45 * size
    x, y = pixel_grid((size, size))
    r2 = x * x + y * y
    mask = r2 < R * R
    z = np.sqrt(np.maximum(R * R - r2, 0.0))
    n = np.empty((size, size, 3), dtype=np.float32)
    n[..., 0] = np.broadcast_to(x / R, r2.shape)
    n[..., 1] = np.broadcast_to(y / R, r2.shape)
    n[..., 2] = z / R
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return _finish("semisphere", np.where(mask, z, 0.0), mask, n)


#: (x, y, radius) of the ``spheres`` surface as fractions of the size (x right, y up).
_SPHERES = ((-0.20, 0.18, 0.22), (0.25, 0.25, 0.16), (0.26, -0.20, 0.19),
            (-0.24, -0.27, 0.13), (0.00, -0.05, 0.08))


def _spheres(size):
    x, y = pixel_grid((size, size))
    z = np.zeros((size, size))
    nx = np.zeros((size, size))
    ny = np.zeros((size, size))
    nz = np.ones((size, size))
    for cx, cy, cr in _SPHERES:
        X0, Y0, R = cx * size, cy * size, cr * size
        dx, dy = x - X0, y - Y0
        r2 = dx * dx + dy * dy
        inside = r2 < R * R
        zs = np.sqrt(np.maximum(R * R - r2, 0.0))
        z = np.where(inside, zs, z)
        nx = np.where(inside, dx / R, nx)
        ny = np.where(inside, dy / R, ny)
        nz = np.where(inside, zs / R, nz)
    n = np.stack([nx, ny, nz], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return _finish("spheres", z, np.ones((size, size), dtype=bool), n)


# --------------------------------------------------------------------------- mozart
def _mozart(size):
    """Procedural bust; u, v in [-1, 1] (v up), heights in units of size/2."""
    half = size / 2.0
    x, y = pixel_grid((size, size))
    u, v = x / half, y / half
    # head: ellipsoid; face features are added to it
    head = _dome(u, v, 0.0, 0.18, 0.36, 0.46, 0.42)
    face = (_gauss(u, v, 0.0, 0.07, 0.16, 0.22))          # where features live
    feat = (
        # nose: ridge from the brows to the tip, growing towards the tip, plus nostril wings
        0.085 * _gauss(u, v, 0.0, 0.10, 0.035, 0.10) * np.clip((0.26 - v) / 0.2, 0.0, 1.0) ** 0.7
        + 0.030 * _gauss(u, v, 0.0, 0.02, 0.030, 0.025)
        + 0.018 * _gauss(u, v, -0.045, 0.025, 0.022, 0.02)
        + 0.018 * _gauss(u, v, 0.045, 0.025, 0.022, 0.02)
        # eye sockets with eyeballs
        - 0.060 * _gauss(u, v, -0.13, 0.19, 0.060, 0.045)
        - 0.060 * _gauss(u, v, 0.13, 0.19, 0.060, 0.045)
        + 0.030 * _gauss(u, v, -0.13, 0.185, 0.030, 0.022)
        + 0.030 * _gauss(u, v, 0.13, 0.185, 0.030, 0.022)
        # brows
        + 0.030 * _gauss(u, v, -0.14, 0.27, 0.075, 0.022)
        + 0.030 * _gauss(u, v, 0.14, 0.27, 0.075, 0.022)
        # lips (upper, lower) with the mouth groove between, chin, cheeks
        + 0.028 * _gauss(u, v, 0.0, -0.075, 0.070, 0.018)
        + 0.030 * _gauss(u, v, 0.0, -0.125, 0.060, 0.020)
        - 0.018 * _gauss(u, v, 0.0, -0.100, 0.080, 0.008)
        + 0.035 * _gauss(u, v, 0.0, -0.21, 0.070, 0.045)
        + 0.020 * _gauss(u, v, -0.17, 0.02, 0.07, 0.07)
        + 0.020 * _gauss(u, v, 0.17, 0.02, 0.07, 0.07)
    )
    # face features only where the head dome exists
    head_on = np.clip(head / 0.1, 0.0, 1.0)
    head = head + feat * head_on * np.minimum(face / 0.3, 1.0)
    # ears
    ears = (_dome(u, v, -0.36, 0.14, 0.05, 0.10, 0.16)
            + _dome(u, v, 0.36, 0.14, 0.05, 0.10, 0.16))
    # hair: volume over the crown and the sides, open over the face, with wavy curls
    hair = _dome(u, v, 0.0, 0.28, 0.48, 0.50, 0.40)
    ang = np.arctan2(v - 0.1, u)
    rad = np.sqrt(u * u + (v - 0.1) ** 2)
    curls = 0.022 * np.sin(26.0 * ang + 9.0 * np.sin(3.0 * ang) + 30.0 * rad) \
        + 0.012 * np.sin(55.0 * rad)
    hair = np.where(hair > 0, hair + curls * np.clip(hair / 0.08, 0.0, 1.0), 0.0)
    # hairline: remove the hair over the face (forehead down), keep it above and behind
    open_face = np.clip(1.0 - _dome(u, v, 0.0, 0.02, 0.30, 0.38, 1.0, power=1.0) * 2.5, 0.0, 1.0)
    hair = hair * open_face - 0.15 * (1.0 - open_face)
    # neck and shoulders (bust)
    neck = _dome(u, v, 0.0, -0.45, 0.19, 0.40, 0.26)
    bust = _dome(u, v, 0.0, -1.20, 0.95, 0.68, 0.34)
    collar = 0.025 * _gauss(u, v, 0.0, -0.62, 0.35, 0.03) * (bust > 0)
    def blend(*parts):
        z = _smax(parts[0], parts[1], 80.0)
        for part in parts[2:]:
            z = _smax(z, part, 60.0)
        return z

    # the log-sum-exp blend lifts the plane (where every part is 0) by a constant: take
    # that level off so the background plane sits at height 0 (beside the face, where the
    # hair term is negative, the plane dips gently below 0, by about 1 % of the bust height)
    plane = float(blend(*([np.zeros(1)] * 5))[0])
    z = blend(head, ears, hair, neck, bust + collar) - plane
    height = z * half
    mask = np.ones((size, size), dtype=bool)
    return _finish("mozart", height, mask, normals_from_height(height))


# --------------------------------------------------------------------------- penny
def _penny(size):
    """Coin on a plane; u, v in [-1, 1] (v up), heights in units of size/2."""
    from scipy.ndimage import gaussian_filter

    half = size / 2.0
    x, y = pixel_grid((size, size))
    u, v = x / half, y / half
    r = np.sqrt(u * u + v * v)
    R = 0.90                      # coin radius
    thick = 0.10                  # coin thickness (vertical edge)
    coin = r < R
    # raised rim
    rim = 0.035 * np.clip(1.0 - np.abs(r - 0.85) / 0.045, 0.0, 1.0) ** 0.6
    # bust in profile facing right: union of low domes
    parts = [
        (-0.05, 0.14, 0.26, 0.30, 0.045),   # cranium
        (0.12, 0.06, 0.15, 0.22, 0.040),    # face
        (0.27, 0.09, 0.06, 0.05, 0.035),    # nose
        (0.20, -0.09, 0.09, 0.07, 0.030),   # lips/chin
        (0.10, -0.15, 0.17, 0.12, 0.035),   # beard/jaw
        (0.00, -0.32, 0.14, 0.18, 0.035),   # neck
        (-0.05, -0.58, 0.40, 0.17, 0.040),  # shoulders/coat
        (0.03, 0.20, 0.04, 0.03, 0.015),    # eye brow ridge
    ]
    relief = np.zeros_like(u * v)
    for u0, v0, a, b, c in parts:
        relief = _smax(relief, _dome(u, v, u0, v0, a, b, c, power=0.6), 300.0)
    relief = np.where(relief < 1e-3, 0.0, relief)
    # hair texture on the cranium and an eye
    hair = 0.006 * np.sin(40.0 * np.arctan2(v - 0.14, u + 0.05) + 25.0 * r) \
        * (_dome(u, v, -0.08, 0.18, 0.22, 0.26, 1.0) > 0)
    eye = -0.008 * _gauss(u, v, 0.15, 0.14, 0.02, 0.012)
    relief = (relief + (hair + eye) * (relief > 0.02)) * (r < 0.62)
    # lettering-like ring: words along arcs, letters as radial strokes
    theta = np.arctan2(v, u)
    r_lt = 0.72
    band = np.exp(-0.5 * ((r - r_lt) / 0.035) ** 2)
    strokes = np.clip(np.cos(70.0 * theta) * 0.6 + np.cos(35.0 * theta + 1.3) * 0.5
                      + np.sin(140.0 * theta) * 0.3 * np.sin(40.0 * (r - r_lt) / 0.1), 0.0, None)
    # words: top arc (gap at the sides), left arc, right arc (the year)
    deg = np.degrees(theta)
    words = ((np.abs(deg - 90.0) < 55.0) & (np.abs(deg - 90.0) > 3.0)) \
        | ((deg > 150.0) | (deg < -150.0)) | ((deg > -40.0) & (deg < 5.0))
    letters = 0.022 * band * np.minimum(strokes, 1.0) * words
    top = thick + rim + relief + letters
    z = np.where(coin, top, 0.0)
    # soften by ~0.6 px (no sub-pixel aliasing); the coin edge stays steep
    z = gaussian_filter(z, sigma=0.6, mode="nearest")
    height = z * half
    mask = np.ones((size, size), dtype=bool)
    return _finish("penny", height, mask, normals_from_height(height))


# --------------------------------------------------------------------------- public
def make_surface(name, size=512):
    """Make a named test surface.

    Parameters
    ----------
    name : str
        One of :data:`SURFACES`: ``semisphere``, ``spheres``, ``sombrero``
        (= ``sombrero2``), ``sombrero1``, ``sombrero2``, ``sombrero3``,
        ``mozart``, ``penny``.
    size : int, default 512
        Side of the square (size, size) grid, >= 16. Shapes scale with the
        size: heights are in pixel units, so slopes and zeniths do not depend
        on it (up to sampling).

    Returns
    -------
    Surface
        ``.height (size, size) float32``, ``.mask (size, size) bool``,
        ``.normals (size, size, 3) float32``; deterministic.
    """
    choice(name, SURFACES, "name")
    size = _check_size(size)
    if name == "sombrero":
        s = _sombrero("sombrero2", size)
        return Surface(name="sombrero", height=s.height, mask=s.mask, normals=s.normals)
    if name in SOMBRERO_PEAKS:
        return _sombrero(name, size)
    return {"semisphere": _semisphere, "spheres": _spheres, "mozart": _mozart,
            "penny": _penny}[name](size)


def surface_from_height(height, mask=None, name="custom"):
    """Wrap any height map as a :class:`Surface` (normals by central differences).

    Parameters
    ----------
    height : (H, W) array_like of float or int
        Finite heights in pixel units, H, W >= 2.
    mask : (H, W) bool array_like, optional
        Object mask; default all True. Outside it the normals are set to
        (0, 0, 1); the heights are kept as given (they are the background the
        object sits on, and they enter the central differences at the mask's
        border).
    name : str, default "custom"

    Returns
    -------
    Surface
    """
    arr = np.asarray(height)
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.integer)
                                 or np.issubdtype(arr.dtype, np.floating)):
        raise PsbenchError(f"height must be a float or integer array, got dtype {arr.dtype}")
    if arr.ndim != 2:
        raise PsbenchError(f"height must have shape (H, W), got shape {arr.shape}")
    if arr.shape[0] < 2 or arr.shape[1] < 2:
        raise PsbenchError(f"height must be at least 2 x 2, got shape {arr.shape}")
    z = arr.astype(np.float64)
    if not np.isfinite(z).all():
        bad = int((~np.isfinite(z)).sum())
        raise PsbenchError(f"height holds {bad} NaN/inf values; fill or crop them first")
    m = as_mask(mask, z.shape, "mask")
    return _finish(str(name), z, np.asarray(m, dtype=bool), normals_from_height(z))


def surface_from_file(path, *, scale=None, mask=None, name=None):
    """Read a height map from ``.npy`` or 16-bit ``.png`` into a :class:`Surface`.

    Parameters
    ----------
    path : str or Path
        ``.npy``: a 2-D numeric array of heights in pixel units, multiplied by
        ``scale`` (default 1).
        ``.png``: a single-channel 16-bit (or 8-bit) image read with OpenCV
        (``cv2.IMREAD_UNCHANGED``). A value ``v`` maps to the height
        ``v / vmax * scale`` pixels, where ``vmax`` is 65535 (255 for 8-bit)
        and ``scale`` defaults to ``width / 4``: the full 16-bit range spans a
        quarter of the image width.
    scale : float, optional
        See above.
    mask : (H, W) bool array_like, optional
        Object mask (default all True).
    name : str, optional
        Default: the file's stem.

    Returns
    -------
    Surface
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in (".npy", ".png"):
        raise PsbenchError(f"path must end in .npy or .png, got {str(path)!r}")
    if not p.is_file():
        raise PsbenchError(f"path {str(path)!r} does not exist or is not a file")
    if scale is not None:
        scale = float(scale)
        if not math.isfinite(scale) or scale <= 0:
            raise PsbenchError(f"scale must be a positive finite number, got {scale}")
    if ext == ".npy":
        try:
            arr = np.load(p, allow_pickle=False)
        except Exception as exc:  # noqa: BLE001 - report any reader failure clearly
            raise PsbenchError(f"path {str(path)!r} is not a readable .npy array: {exc}") from exc
        if arr.dtype == bool or not np.issubdtype(arr.dtype, np.number):
            raise PsbenchError(f"{p.name} must hold a numeric array, got dtype {arr.dtype}")
        height = arr.astype(np.float64) * (1.0 if scale is None else scale)
    else:
        import cv2

        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise PsbenchError(f"path {str(path)!r} is not a readable PNG")
        if img.ndim == 3:
            if img.shape[2] >= 3 and np.array_equal(img[..., 0], img[..., 1]) \
                    and np.array_equal(img[..., 1], img[..., 2]):
                img = img[..., 0]
            else:
                raise PsbenchError(f"{p.name} must be a single-channel (grey) height PNG, "
                                   f"got {img.shape[2]} channels")
        if img.dtype not in (np.uint16, np.uint8):
            raise PsbenchError(f"{p.name} must be a 16-bit (or 8-bit) PNG, got dtype {img.dtype}")
        vmax = float(np.iinfo(img.dtype).max)
        full = img.shape[1] / 4.0 if scale is None else scale
        height = img.astype(np.float64) / vmax * full
    return surface_from_height(height, mask=mask, name=p.stem if name is None else name)


# --------------------------------------------------------------------------- previews
def _shade(surface, light=(-1.0, 1.0, 1.5)):
    """Lambert shading max(0, n.l) with one light from the upper left (no cast shadows)."""
    ldir = np.asarray(light, dtype=np.float64)
    ldir = ldir / np.linalg.norm(ldir)
    return np.clip(surface.normals.astype(np.float64) @ ldir, 0.0, 1.0)


def write_preview(surface, path):
    """Write a PNG: height colour map and a shaded Lambert render side by side.

    Written atomically (temporary file in the same directory, then ``os.replace``).
    """
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    h = np.ma.masked_array(surface.height, mask=~surface.mask)
    shade = np.where(surface.mask, _shade(surface), 0.0)
    fig = Figure(figsize=(7.2, 3.2), dpi=100)
    ax1, ax2 = fig.subplots(1, 2)
    im = ax1.imshow(h, cmap="viridis", interpolation="nearest")
    fig.colorbar(im, ax=ax1, fraction=0.046, pad=0.03, label="height [px]")
    ax1.set_title(f"{surface.name}: height", fontsize=9)
    ax2.imshow(shade, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    ax2.set_title(f"Lambert, max zenith {float(surface.zenith[surface.mask].max()):.1f}°",
                  fontsize=9)
    for ax in (ax1, ax2):
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    atomic_write(path, lambda fh: fig.savefig(fh, format="png"), fsync=False)
    return path


def main(argv=None):
    """Console script ``psbench-surfaces``: write preview PNGs of the named surfaces."""
    import argparse

    parser = argparse.ArgumentParser(
        prog="psbench-surfaces",
        description="Write preview PNGs (height colour map + Lambert shading) of psbench surfaces.")
    parser.add_argument("--out", default="surfaces", help="output directory (default: ./surfaces)")
    parser.add_argument("--size", type=int, default=256, help="grid size (default: 256)")
    parser.add_argument("--names", nargs="+", default=list(SURFACES), metavar="NAME",
                        help=f"surfaces to draw (default: all of {', '.join(SURFACES)})")
    args = parser.parse_args(argv)
    try:
        for name in args.names:
            choice(name, SURFACES, "--names")
        _check_size(args.size)
    except PsbenchError as exc:
        parser.error(str(exc))
    for name in args.names:
        out = write_preview(make_surface(name, args.size), Path(args.out) / f"{name}.png")
        print(out)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
