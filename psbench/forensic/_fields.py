"""Random height fields of the cartridge model (pure functions of a numpy Generator).

Every field is in micrometres on a square grid of a given spacing. The gun's marks are
generated once on a *gun grid* of fixed spacing (:data:`GUN_SPACING`), independent of the
image's pixel size, so the same gun leaves the same marks on every case at every
resolution; the cartridge then samples that grid through the case's pose
(:func:`sample`).
"""
from __future__ import annotations

import functools
import math

import cv2
import numpy as np
import scipy.fft as sfft

#: spacing (µm) of the grid the gun's marks are generated on
GUN_SPACING = 2.45
#: samples per side of the gun grid (covers a disc of radius ~2.5 mm: the primer)
GUN_GRID = 2048


def _freq(n, spacing):
    """Log radial spatial frequency (log 1/µm) and angle of an (n, n//2+1) rfft2 grid."""
    fy = sfft.fftfreq(n, d=spacing).astype(np.float32)[:, None]
    fx = sfft.rfftfreq(n, d=spacing).astype(np.float32)[None, :]
    f = np.hypot(fx, fy)
    f[0, 0] = np.float32(1e-12)
    return np.log(f), np.arctan2(fy, fx)


def band(rng, n, spacing, lo, hi, *, direction=None, spread=None):
    """Gaussian random field with wavelengths in [lo, hi] µm, unit RMS, (n, n) float32.

    The spectrum is flat inside the band with log-Gaussian roll-offs outside (no ringing
    of a hard box). ``direction`` and ``spread`` (radians) make it anisotropic: the wave
    vectors lie within ~``spread`` of ``direction``, so the field is made of lines
    perpendicular to ``direction`` (striations), each about ``wavelength / spread`` long.
    """
    logf, ang = _freq(n, spacing)
    above = np.maximum(logf - np.float32(-math.log(lo)), 0)     # beyond 1/lo
    below = np.maximum(np.float32(-math.log(hi)) - logf, 0)     # below 1/hi
    expo = (above * above + below * below) * np.float32(-0.5 / 0.35 ** 2)
    if direction is not None:
        d = np.abs((ang - np.float32(direction) + np.float32(np.pi)) % np.float32(2 * np.pi)
                   - np.float32(np.pi))
        d = np.minimum(d, np.float32(np.pi) - d)                  # the field is real: +-k
        expo -= d * d * np.float32(0.5 / spread ** 2)
    amp = np.exp(expo)
    amp[0, 0] = 0.0
    noise = rng.standard_normal((n, n), dtype=np.float32)
    spec = sfft.rfft2(noise, workers=-1)
    spec *= amp
    field = sfft.irfft2(spec, s=(n, n), workers=-1).astype(np.float32)
    rms = float(np.sqrt(np.mean(field * field)))
    return field / np.float32(rms) if rms > 0 else field


def grid_xy(n, spacing):
    """Coordinates (µm) of an (n, n) grid centred on 0: x (1, n) right, y (n, 1) up."""
    c = (np.arange(n, dtype=np.float32) - np.float32((n - 1) / 2)) * np.float32(spacing)
    return c[None, :], -c[:, None]


def _box(x, y, x0, x1, y0, y1):
    """Index slices of the axis-aligned grid (x (1, n) increasing, y (m, 1) decreasing)
    covering [x0, x1] x [y0, y1]."""
    xs, ys = x[0], -y[:, 0]
    c = slice(int(np.searchsorted(xs, x0)), int(np.searchsorted(xs, x1, side="right")))
    r = slice(int(np.searchsorted(ys, -y1)), int(np.searchsorted(ys, -y0, side="right")))
    return r, c


def segments(x, y, lines):
    """Grooves along segments on a grid: ``lines`` rows (x0, y0, x1, y1, depth, width) µm.

    ``x`` (1, n) increasing and ``y`` (m, 1) decreasing are grid coordinates (µm). Each
    groove has a Gaussian cross-section (``width`` = 1/e² half width) and rounded ends;
    ``depth`` > 0 cuts into the surface. Evaluated on each groove's bounding box only.
    """
    out = np.zeros((y.shape[0], x.shape[1]), dtype=np.float32)
    for x0, y0, x1, y1, depth, width in lines:  # a handful of grooves
        m = 2.5 * width
        r, c = _box(x, y, min(x0, x1) - m, max(x0, x1) + m, min(y0, y1) - m, max(y0, y1) + m)
        xx, yy = x[:, c], y[r, :]
        dx, dy = x1 - x0, y1 - y0
        L2 = max(dx * dx + dy * dy, 1e-9)
        t = np.clip(((xx - x0) * dx + (yy - y0) * dy) / L2, 0.0, 1.0)
        d2 = (xx - x0 - t * dx) ** 2 + (yy - y0 - t * dy) ** 2
        out[r, c] -= np.float32(depth) * np.exp(-2.0 * d2 / np.float32(width * width))
    return out


def dents(x, y, spots):
    """Gaussian dents/bumps on a grid: ``spots`` rows (x0, y0, radius, depth) µm, depth > 0
    dents; grid as in :func:`segments`."""
    out = np.zeros((y.shape[0], x.shape[1]), dtype=np.float32)
    for x0, y0, rad, depth in spots:
        m = 3.0 * rad
        r, c = _box(x, y, x0 - m, x0 + m, y0 - m, y0 + m)
        d2 = (x[:, c] - x0) ** 2 + (y[r, :] - y0) ** 2
        out[r, c] -= np.float32(depth) * np.exp(-d2 / np.float32(rad * rad))
    return out


def smoothstep(t):
    """0 below 0, 1 above 1, C1 cubic in between."""
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


@functools.lru_cache(maxsize=6)
def gun_marks(gun):
    """The gun's marks and geometry, deterministic per ``gun`` seed.

    Cached (a few recent guns): the grids are read-only, and every case fired by a gun
    samples the same ones.

    Returns
    -------
    marks : dict
        ``breech`` (GUN_GRID, GUN_GRID) float32 µm: breech-face impression field, a mix
        of filed striations, turning arcs and granular texture of RMS ``bf_rms``, plus a
        few long scratches and dents. ``tip`` (same shape): the firing-pin tip's own marks.
        Scalars: ``fp_radius``, ``fp_depth``, ``fp_wall`` (degrees), ``fp_curv``,
        ``fp_lip``, ``ejector_angle`` (rad, gun frame), ``ejector_size`` (a, b) µm,
        ``ejector_depth``, ``bf_rms``.
    """
    rng = np.random.default_rng([0x6A11, gun])
    n, sp = GUN_GRID, GUN_SPACING
    x, y = grid_xy(n, sp)
    alpha = rng.uniform(0, np.pi)                       # direction across the filed lines
    w_file, w_arc, w_gran = rng.dirichlet([3.0, 1.0, 1.5])
    filed = band(rng, n, sp, 18.0, 220.0, direction=alpha, spread=math.radians(rng.uniform(2, 5)))
    gran = band(rng, n, sp, 16.0, 120.0)
    # turning arcs: a 1-D profile in the distance from a centre near the firing pin
    c0 = rng.normal(0, 300.0, 2)
    rho = np.sqrt((x - np.float32(c0[0])) ** 2 + (y - np.float32(c0[1])) ** 2)
    k = rng.uniform(1 / 120.0, 1 / 30.0, 6)               # radial wavenumbers, 1/µm
    ph = rng.uniform(0, 2 * np.pi, 6)
    r1 = np.arange(0.0, float(rho.max()) + 1.0, 0.5)      # profile on a fine 1-D grid
    prof = np.cos(2 * np.pi * k[None, :] * r1[:, None] + ph[None, :]).sum(axis=1) / np.sqrt(3.0)
    arcs = np.interp(rho, r1, prof).astype(np.float32)
    breech = w_file * filed + w_arc * arcs + w_gran * gran
    breech /= np.float32(np.sqrt(np.mean(breech * breech)))
    # long scratches (the examiner's "diagonal long lines") and impressed dents
    ns = int(rng.integers(2, 7))
    a = alpha + np.pi / 2 + rng.normal(0, math.radians(12), ns)   # roughly along the lines
    cx, cy = rng.uniform(-1800, 1800, (2, ns))
    half = rng.uniform(300, 1500, ns)
    lines = np.column_stack([cx - half * np.cos(a), cy - half * np.sin(a),
                             cx + half * np.cos(a), cy + half * np.sin(a),
                             rng.uniform(1.5, 4.0, ns), rng.uniform(12, 30, ns)])
    npits = int(rng.integers(10, 31))
    spots = np.column_stack([rng.uniform(-2200, 2200, (2, npits)).T,
                             rng.uniform(15, 50, npits),
                             rng.uniform(-2.5, 3.5, npits)])
    bf_rms = float(rng.uniform(1.0, 1.8))
    breech = bf_rms * breech + segments(x, y, lines) + dents(x, y, spots)
    # firing-pin tip: its own fine texture and one or two short lines near the centre
    fp_radius = float(rng.uniform(560.0, 780.0))
    tip = 0.8 * band(rng, n, sp, 16.0, 100.0, direction=rng.uniform(0, np.pi),
                     spread=math.radians(8))
    nt = int(rng.integers(1, 3))
    b = rng.uniform(0, np.pi, nt)
    tx, ty = rng.uniform(-0.3, 0.3, (2, nt)) * fp_radius
    th = rng.uniform(0.15, 0.35, nt) * fp_radius
    tip += segments(x, y, np.column_stack([tx - th * np.cos(b), ty - th * np.sin(b),
                                           tx + th * np.cos(b), ty + th * np.sin(b),
                                           rng.uniform(2.0, 5.0, nt), rng.uniform(10, 20, nt)]))
    breech, tip = breech.astype(np.float32), tip.astype(np.float32)
    breech.setflags(write=False)
    tip.setflags(write=False)
    return {
        "breech": breech, "tip": tip,
        "fp_radius": fp_radius, "fp_depth": float(rng.uniform(140.0, 240.0)),
        "fp_wall": float(rng.uniform(60.0, 75.0)), "fp_curv": float(rng.uniform(0.2, 0.45)),
        "fp_lip": float(rng.uniform(4.0, 15.0)),
        "ejector_angle": float(rng.uniform(0, 2 * np.pi)),
        "ejector_size": (float(rng.uniform(200, 320)), float(rng.uniform(120, 200))),
        "ejector_depth": float(rng.uniform(15.0, 35.0)), "bf_rms": bf_rms,
    }


def sample(field, x, y, *, spacing, pixel_size):
    """Sample a centred grid ``field`` (spacing µm) at points (x, y) µm, bilinear.

    Low-passes the field first when the pixel is coarser than the grid (a camera pixel
    integrates over its area: no aliasing). Points off the grid get 0.
    """
    f = field
    ratio = pixel_size / spacing
    if ratio > 1.0:
        f = cv2.GaussianBlur(field, (0, 0), sigmaX=0.45 * math.sqrt(ratio * ratio - 1.0))
    n = field.shape[0]
    c0 = np.float32((n - 1) / 2)
    mx = (x / np.float32(spacing) + c0).astype(np.float32)
    my = (c0 - y / np.float32(spacing)).astype(np.float32)
    return cv2.remap(f, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0)
