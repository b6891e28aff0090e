"""``sombrero1``: the sombrero of peak A = 1750 (thesis Chapter 4), largest zenith ≈ 48.3°.

See :mod:`psbench.surfaces._sombrero` for the family's definition.
"""
from __future__ import annotations

from ..registry import SurfaceSpec
from ._sombrero import sombrero


def sombrero1(size):
    """sombrero1 on a (size, size) grid: heights in pixel units, analytic normals."""
    return sombrero("sombrero1", size)


SURFACE = SurfaceSpec("sombrero1", sombrero1,
                      help="z = A sin(r/λ)/(r/λ), A = 1750, max zenith 48.3°")
