"""``mozart``: a procedural bust in the spirit of the Mozart height map.

Head with nose, eye sockets, brows, lips and chin, a hair volume with wavy curls, neck
and shoulders, standing on a background plane (height 0) that is part of the object
mask. Its sides are steep, so it casts shadows on the plane. Normals by central
differences of the height.
"""
from __future__ import annotations

import numpy as np

from ..registry import SurfaceSpec
from ._surface import dome, finish, gauss, normals_from_height, pixel_grid, smax


def mozart(size):
    """Procedural bust; u, v in [-1, 1] (v up), heights in units of size/2."""
    half = size / 2.0
    x, y = pixel_grid((size, size))
    u, v = x / half, y / half
    # head: ellipsoid; face features are added to it
    head = dome(u, v, 0.0, 0.18, 0.36, 0.46, 0.42)
    face = (gauss(u, v, 0.0, 0.07, 0.16, 0.22))          # where features live
    feat = (
        # nose: ridge from the brows to the tip, growing towards the tip, plus nostril wings
        0.085 * gauss(u, v, 0.0, 0.10, 0.035, 0.10) * np.clip((0.26 - v) / 0.2, 0.0, 1.0) ** 0.7
        + 0.030 * gauss(u, v, 0.0, 0.02, 0.030, 0.025)
        + 0.018 * gauss(u, v, -0.045, 0.025, 0.022, 0.02)
        + 0.018 * gauss(u, v, 0.045, 0.025, 0.022, 0.02)
        # eye sockets with eyeballs
        - 0.060 * gauss(u, v, -0.13, 0.19, 0.060, 0.045)
        - 0.060 * gauss(u, v, 0.13, 0.19, 0.060, 0.045)
        + 0.030 * gauss(u, v, -0.13, 0.185, 0.030, 0.022)
        + 0.030 * gauss(u, v, 0.13, 0.185, 0.030, 0.022)
        # brows
        + 0.030 * gauss(u, v, -0.14, 0.27, 0.075, 0.022)
        + 0.030 * gauss(u, v, 0.14, 0.27, 0.075, 0.022)
        # lips (upper, lower) with the mouth groove between, chin, cheeks
        + 0.028 * gauss(u, v, 0.0, -0.075, 0.070, 0.018)
        + 0.030 * gauss(u, v, 0.0, -0.125, 0.060, 0.020)
        - 0.018 * gauss(u, v, 0.0, -0.100, 0.080, 0.008)
        + 0.035 * gauss(u, v, 0.0, -0.21, 0.070, 0.045)
        + 0.020 * gauss(u, v, -0.17, 0.02, 0.07, 0.07)
        + 0.020 * gauss(u, v, 0.17, 0.02, 0.07, 0.07)
    )
    # face features only where the head dome exists
    head_on = np.clip(head / 0.1, 0.0, 1.0)
    head = head + feat * head_on * np.minimum(face / 0.3, 1.0)
    # ears
    ears = (dome(u, v, -0.36, 0.14, 0.05, 0.10, 0.16)
            + dome(u, v, 0.36, 0.14, 0.05, 0.10, 0.16))
    # hair: volume over the crown and the sides, open over the face, with wavy curls
    hair = dome(u, v, 0.0, 0.28, 0.48, 0.50, 0.40)
    ang = np.arctan2(v - 0.1, u)
    rad = np.sqrt(u * u + (v - 0.1) ** 2)
    curls = 0.022 * np.sin(26.0 * ang + 9.0 * np.sin(3.0 * ang) + 30.0 * rad) \
        + 0.012 * np.sin(55.0 * rad)
    hair = np.where(hair > 0, hair + curls * np.clip(hair / 0.08, 0.0, 1.0), 0.0)
    # hairline: remove the hair over the face (forehead down), keep it above and behind
    open_face = np.clip(1.0 - dome(u, v, 0.0, 0.02, 0.30, 0.38, 1.0, power=1.0) * 2.5, 0.0, 1.0)
    hair = hair * open_face - 0.15 * (1.0 - open_face)
    # neck and shoulders (bust)
    neck = dome(u, v, 0.0, -0.45, 0.19, 0.40, 0.26)
    bust = dome(u, v, 0.0, -1.20, 0.95, 0.68, 0.34)
    collar = 0.025 * gauss(u, v, 0.0, -0.62, 0.35, 0.03) * (bust > 0)
    def blend(*parts):
        z = smax(parts[0], parts[1], 80.0)
        for part in parts[2:]:
            z = smax(z, part, 60.0)
        return z

    # the log-sum-exp blend lifts the plane (where every part is 0) by a constant: take
    # that level off so the background plane sits at height 0 (beside the face, where the
    # hair term is negative, the plane dips gently below 0, by about 1 % of the bust height)
    plane = float(blend(*([np.zeros(1)] * 5))[0])
    z = blend(head, ears, hair, neck, bust + collar) - plane
    height = z * half
    object_mask = np.ones((size, size), dtype=bool)
    return finish("mozart", height, object_mask, normals_from_height(height))


SURFACE = SurfaceSpec("mozart", mozart,
                      help="procedural bust on a plane (steep sides, cast shadows)")
