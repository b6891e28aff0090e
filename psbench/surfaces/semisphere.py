"""``semisphere``: a hemisphere of radius ``0.45 * size`` standing on a ground plane.

The plane (height 0) is part of the object mask, so the hemisphere's cast shadows on
it count in NE, as in the thesis's Figs. 5.16-5.17 ("cast shadow errors were
accumulated around the objects", "errors due to the cast shadows appeared around ...
the sphere", lines ~1260-1262). ``plane=False`` gives the disc-only scene, also
registered as ``semisphere_disc`` (:mod:`psbench.surfaces.semisphere_disc`): the object
mask is the disc and the background is not part of the object. Analytic normals.
"""
from __future__ import annotations

import numpy as np

from ..registry import SurfaceSpec
from ._surface import finish, pixel_grid


def semisphere(size, *, plane=True):
    """The hemisphere on a (size, size) grid (heights in pixel units).

    Parameters
    ----------
    size : int
    plane : bool, default True
        The ground plane around the hemisphere is part of the object mask (True) or
        the object mask is the hemisphere's disc only (False; the surface is then
        named ``semisphere_disc``).
    """
    R = 0.45 * size
    x, y = pixel_grid((size, size))
    r2 = x * x + y * y
    disc = r2 < R * R
    z = np.sqrt(np.maximum(R * R - r2, 0.0))
    n = np.empty((size, size, 3), dtype=np.float32)
    n[..., 0] = np.where(disc, x / R, 0.0)
    n[..., 1] = np.where(disc, y / R, 0.0)
    n[..., 2] = np.where(disc, z / R, 1.0)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    height = np.where(disc, z, 0.0)
    if plane:
        return finish("semisphere", height, np.ones((size, size), dtype=bool), n)
    return finish("semisphere_disc", height, disc, n)


SURFACE = SurfaceSpec("semisphere", semisphere,
                      help="hemisphere of radius 0.45 size on a ground plane that is part "
                           "of the object (plane=False: the disc only)")
