"""Test surfaces: height maps with object masks and unit normals.

Every surface lives in the psbench frame (thesis 2.2): x to the right, y up
(``y = -row``), the camera at +z looking down -z, heights in **pixel units**.
Pixel (row ``r``, column ``c``) of an (H, W) map sits at
``x = c - (W - 1) / 2``, ``y = (H - 1) / 2 - r``. A surface ``z(x, y)`` has the
unit normal ``n ∝ (-dz/dx, -dz/dy, 1)``.

Named surfaces are plug-ins (:class:`psbench.registry.SurfaceSpec`, entry-point group
``psbench.surfaces``); :func:`make_surface` looks the name up and :data:`SURFACES`
lists every registered name. psbench's own, one module each:

``semisphere``
    A hemisphere of radius ``0.45 * size`` centred in the frame, standing on a ground
    plane (height 0) that is part of the object mask, so its cast shadows count (the
    thesis's "errors ... around the sphere"). Analytic normals.
``semisphere_disc``
    The same hemisphere with the object mask its disc only (the background is not part
    of the object).
``spheres``
    Five non-overlapping hemispheres of different radii standing on a flat
    plane (height 0). The plane is part of the object mask, so the spheres cast
    shadows on it. Analytic normals.
``sombrero1``, ``sombrero2``, ``sombrero3``
    ``z = A sin(r/λ) / (r/λ)`` on ``[-7200, 7200]²`` (thesis Chapter 4) with
    peaks ``A = 1750, 3500, 7000``; one ``λ`` (:data:`SOMBRERO_LAMBDA`) for
    all three, chosen so that sombrero2's largest surface zenith is 66°
    (thesis Fig. 4.9). Mapped onto the size × size grid; heights scaled by
    ``size / 14400`` into pixel units. The object mask is the whole square.
    Analytic normals. ``sombrero`` (Chapter 5) is sombrero2.
``mozart``
    A procedural bust in the spirit of the Mozart height map: head with nose,
    eye sockets, brows, lips and chin, a hair volume with wavy curls, neck and
    shoulders, standing on a background plane (height 0) that is part of the
    object mask. Its sides are steep, so it casts shadows on the plane. Normals
    by central differences of the height.
``penny``
    A coin lying on a background plane (height 0, part of the object mask): a
    disc with a vertical edge and a raised rim, a low-relief embossed bust in
    profile and a lettering-like ring of small bumps. Normals by central
    differences of the height.

A new surface is one module exposing ``SURFACE = SurfaceSpec(name, func, help,
aliases)`` with ``func(size, **options) -> Surface``, declared under
``[project.entry-points."psbench.surfaces"]``; ``make_surface(name, size=...,
**options)`` passes the options on.

User height maps: :func:`surface_from_height` and :func:`surface_from_file` (``.npy``,
16-bit ``.png`` and ``.x3p``). Measured topographies (:class:`Topography`, heights in µm,
read from X3P files by :func:`psbench.io.read_x3p`) become surfaces through
:func:`surface_from_topography` (heights divided by the pixel size into pixel units, the
valid points as the object mask).
The command ``psbench-surfaces`` (:func:`main`) writes preview PNGs.

All functions are pure (no caches, no global state) and vectorized.
"""
from __future__ import annotations

from .. import registry
from ._make import make_surface, surface_from_file, surface_from_height
from ._preview import main, write_preview
from ._sombrero import SOMBRERO_HALF, SOMBRERO_LAMBDA, SOMBRERO_PEAKS, sombrero_lambda
from ._surface import MIN_SIZE, Surface, normals_from_height, pixel_grid
from ._topography import Topography, read_topography, surface_from_topography

__all__ = ["Surface", "SURFACES", "SOMBRERO_LAMBDA", "SOMBRERO_PEAKS", "SOMBRERO_HALF",
           "MIN_SIZE", "make_surface", "surface_from_height", "surface_from_file",
           "normals_from_height", "pixel_grid", "sombrero_lambda", "write_preview", "main",
           "Topography", "read_topography", "surface_from_topography"]


def __getattr__(name):
    # SURFACES is read from the registry on every access, so surfaces that plug-ins
    # register (installed or at run time) are listed too
    if name == "SURFACES":
        return tuple(registry.names("surfaces"))
    raise AttributeError(f"module 'psbench.surfaces' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | {"SURFACES"})
