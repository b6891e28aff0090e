"""``semisphere``: a hemisphere of radius ``0.45 * size`` centred in the frame.

The object mask is its disc; the background (height 0) is not part of the object.
Analytic normals.
"""
from __future__ import annotations

import numpy as np

from ..registry import SurfaceSpec
from ._surface import finish, pixel_grid


def semisphere(size):
    """The hemisphere on a (size, size) grid (heights in pixel units)."""
    R = 0.45 * size
    x, y = pixel_grid((size, size))
    r2 = x * x + y * y
    object_mask = r2 < R * R
    z = np.sqrt(np.maximum(R * R - r2, 0.0))
    n = np.empty((size, size, 3), dtype=np.float32)
    n[..., 0] = np.broadcast_to(x / R, r2.shape)
    n[..., 1] = np.broadcast_to(y / R, r2.shape)
    n[..., 2] = z / R
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return finish("semisphere", np.where(object_mask, z, 0.0), object_mask, n)


SURFACE = SurfaceSpec("semisphere", semisphere,
                      help="hemisphere of radius 0.45 size; object = its disc")
