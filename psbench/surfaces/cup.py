"""``cup``: a concave spherical cap in a plane (interreflection test scene).

See :mod:`psbench.surfaces._concave` for the geometry and its closed-form one-bounce
interreflection.
"""
from __future__ import annotations

from ..registry import SurfaceSpec
from ._concave import cup, cup_geometry

__all__ = ["cup", "cup_geometry", "SURFACE"]

SURFACE = SurfaceSpec("cup", cup, help="concave spherical cap (60 deg half-angle) in a plane; "
                      "object = its opening disc")
