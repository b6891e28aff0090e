"""``vgroove``: a right-angled V-groove in a plane (interreflection test scene).

See :mod:`psbench.surfaces._concave` for the geometry.
"""
from __future__ import annotations

from ..registry import SurfaceSpec
from ._concave import vgroove

__all__ = ["vgroove", "SURFACE"]

SURFACE = SurfaceSpec("vgroove", vgroove, help="right-angled V-groove along y in a plane; "
                      "object = the groove")
