"""Concave test surfaces for interreflections: ``vgroove`` and ``cup``.

Both are dents in a flat plane at height 0 (the plane is background, outside the
object mask), so every point of the dent sees only other points of the dent: light
leaving through the opening never comes back (a ray that rises through the plane's
level cannot meet the plane again). That makes their one-bounce interreflection
checkable against a closed form (``cup``) or an occlusion-free brute-force sum
(both), see :mod:`psbench.render._interreflect`. Registered as the surfaces ``cup`` and
``vgroove`` (modules :mod:`psbench.surfaces.cup`, :mod:`psbench.surfaces.vgroove`).

``cup``
    A concave spherical cap: the sphere of radius ``R`` centred at height
    ``R cos(angle)`` above the plane, cut by it along a circle of radius
    ``a = 0.45 size`` (so ``R = a / sin(angle)``), depth ``R (1 - cos(angle))``.
    The wall's zenith grows from 0 at the bottom to ``angle`` at the rim
    (default 60 deg: the height field stays well sampled; 90 deg would be the
    hemispherical cup with vertical walls). Object mask: the opening disc.
    Analytic normals (towards the sphere's centre).
``vgroove``
    Two planar walls of slope ``angle`` (default 45 deg, a right-angled groove)
    meeting at the apex x = 0, running along y through the whole frame; half
    width ``0.4 size``, depth ``0.4 size tan(angle)``. Object mask: the groove
    ``|x| < 0.4 size``. Analytic normals (each wall faces the other).
"""
from __future__ import annotations

import math

import numpy as np

from .._shared.checks import PsbenchError
from ._surface import Surface, pixel_grid

__all__ = ["cup", "vgroove", "cup_geometry", "CUP_APERTURE", "VGROOVE_HALF_WIDTH"]

#: opening radius of ``cup`` as a fraction of the size
CUP_APERTURE = 0.45
#: half width of ``vgroove`` as a fraction of the size
VGROOVE_HALF_WIDTH = 0.4
MIN_SIZE = 16


def _size(size):
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < MIN_SIZE:
        raise PsbenchError(f"size must be an integer >= {MIN_SIZE}, got {size!r}")
    return int(size)


def _angle(angle, hi):
    try:
        a = float(angle)
    except (TypeError, ValueError):
        a = float("nan")
    if not (0.0 < a < hi):
        raise PsbenchError(f"angle must be a number of degrees in (0, {hi:g}), got {angle!r}")
    return a


def _finish(name, height, object_mask, normals):
    """The :class:`Surface` with flat normals off the object.

    Parameters
    ----------
    name : str
    height : (H, W) array_like
        Heights in pixel units.
    object_mask : (H, W) bool
        Object region.
    normals : (H, W, 3) array_like
        Unit normals; set to (0, 0, 1) outside ``object_mask``.
    """
    normals = np.asarray(normals, dtype=np.float32).copy()
    normals[~object_mask] = (0.0, 0.0, 1.0)
    return Surface(name, np.asarray(height, dtype=np.float32), object_mask, normals)


def cup_geometry(size, angle=60.0):
    """(R, a, centre height) of :func:`cup` in pixel units."""
    a = CUP_APERTURE * size
    R = a / math.sin(math.radians(angle))
    return R, a, R * math.cos(math.radians(angle))


def cup(size=512, *, angle=60.0):
    """A concave spherical cap in a plane (see the module docstring).

    Parameters
    ----------
    size : int
        Side of the (size, size) grid, >= 16.
    angle : float, default 60
        Half-angle of the cap in degrees, in (0, 90): the largest wall zenith.

    Returns
    -------
    Surface
        Heights <= 0 in pixel units, object mask = the opening disc.
    """
    size = _size(size)
    angle = _angle(angle, 90.0)
    R, a, zc = cup_geometry(size, angle)
    x, y = pixel_grid((size, size))
    r2 = np.broadcast_to(x * x + y * y, (size, size))
    object_mask = r2 < a * a
    root = np.sqrt(np.maximum(R * R - r2, 0.0))
    height = np.where(object_mask, zc - root, 0.0)
    n = np.empty((size, size, 3))
    n[..., 0] = -np.broadcast_to(x, (size, size)) / R
    n[..., 1] = -np.broadcast_to(y, (size, size)) / R
    n[..., 2] = root / R
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return _finish("cup", height, object_mask, n)


def vgroove(size=512, *, angle=45.0):
    """A V-groove along y in a plane (see the module docstring).

    Parameters
    ----------
    size : int
        Side of the (size, size) grid, >= 16.
    angle : float, default 45
        Slope of each wall in degrees, in (0, 80).

    Returns
    -------
    Surface
        Heights <= 0 in pixel units, object mask = the groove ``|x| < 0.4 size``.
    """
    size = _size(size)
    angle = _angle(angle, 80.0)
    hw = VGROOVE_HALF_WIDTH * size
    t = math.tan(math.radians(angle))
    x, _ = pixel_grid((size, size))
    x = np.broadcast_to(x, (size, size))
    object_mask = np.abs(x) < hw
    height = np.where(object_mask, -(hw - np.abs(x)) * t, 0.0)
    n = np.empty((size, size, 3))
    n[..., 0] = -np.sign(x) * t
    n[..., 1] = 0.0
    n[..., 2] = 1.0
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return _finish("vgroove", height, object_mask, n)

