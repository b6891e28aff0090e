"""``sombrero2``: the sombrero of peak A = 3500 (thesis Chapter 4), largest zenith 66°.

``sombrero``, the surface of thesis Chapter 5, is this one (an alias). See
:mod:`psbench.surfaces._sombrero` for the family's definition.
"""
from __future__ import annotations

from ..registry import SurfaceSpec
from ._sombrero import sombrero


def sombrero2(size):
    """sombrero2 on a (size, size) grid: heights in pixel units, analytic normals."""
    return sombrero("sombrero2", size)


SURFACE = SurfaceSpec("sombrero2", sombrero2, aliases=("sombrero",),
                      help="z = A sin(r/λ)/(r/λ), A = 3500, max zenith 66.0° (= sombrero)")
