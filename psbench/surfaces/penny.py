"""``penny``: a coin lying on a background plane (height 0, part of the object mask).

A disc with a vertical edge and a raised rim, a low-relief embossed bust in profile and
a lettering-like ring of small bumps. Normals by central differences of the height.
"""
from __future__ import annotations

import numpy as np

from ..registry import SurfaceSpec
from ._surface import dome, finish, gauss, normals_from_height, pixel_grid, smax


def penny(size):
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
        relief = smax(relief, dome(u, v, u0, v0, a, b, c, power=0.6), 300.0)
    relief = np.where(relief < 1e-3, 0.0, relief)
    # hair texture on the cranium and an eye
    hair = 0.006 * np.sin(40.0 * np.arctan2(v - 0.14, u + 0.05) + 25.0 * r) \
        * (dome(u, v, -0.08, 0.18, 0.22, 0.26, 1.0) > 0)
    eye = -0.008 * gauss(u, v, 0.15, 0.14, 0.02, 0.012)
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
    object_mask = np.ones((size, size), dtype=bool)
    return finish("penny", height, object_mask, normals_from_height(height))


SURFACE = SurfaceSpec("penny", penny,
                      help="procedural coin on a plane: rim, embossed bust, lettering")
