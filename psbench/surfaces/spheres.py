"""``spheres``: five non-overlapping hemispheres of different radii on a flat plane.

The plane (height 0) is part of the object mask, so the spheres cast shadows on it.
Analytic normals.
"""
from __future__ import annotations

import numpy as np

from ..registry import SurfaceSpec
from ._surface import finish, pixel_grid

#: (x, y, radius) of the spheres as fractions of the size (x right, y up).
SPHERES = ((-0.20, 0.18, 0.22), (0.25, 0.25, 0.16), (0.26, -0.20, 0.19),
           (-0.24, -0.27, 0.13), (0.00, -0.05, 0.08))


def spheres(size):
    """The five hemispheres on their plane, on a (size, size) grid."""
    x, y = pixel_grid((size, size))
    z = np.zeros((size, size))
    nx = np.zeros((size, size))
    ny = np.zeros((size, size))
    nz = np.ones((size, size))
    for cx, cy, cr in SPHERES:
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
    return finish("spheres", z, np.ones((size, size), dtype=bool), n)


SURFACE = SurfaceSpec("spheres", spheres,
                      help="five hemispheres on a plane that is part of the object")
