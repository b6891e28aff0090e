"""``sombrero3``: the sombrero of peak A = 7000 (thesis Chapter 4), largest zenith ≈ 77.4°.

See :mod:`psbench.surfaces._sombrero` for the family's definition.
"""
from __future__ import annotations

from ..registry import SurfaceSpec
from ._sombrero import sombrero


def sombrero3(size):
    """sombrero3 on a (size, size) grid: heights in pixel units, analytic normals."""
    return sombrero("sombrero3", size)


SURFACE = SurfaceSpec("sombrero3", sombrero3,
                      help="z = A sin(r/λ)/(r/λ), A = 7000, max zenith 77.4°")
