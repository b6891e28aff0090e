"""``cartridge``: the head of a fired cartridge case (Chapter 7), a surface that
psbench.forensic registers (``psbench.surfaces`` entry point), as a plug-in would.

The generator and its ground truth (regions, pose, heights in micrometres) live in
:mod:`psbench.forensic.cartridge`; ``make_surface("cartridge", size=2048, gun=3, case=5)``
passes ``gun``, ``case``, ``pixel_size`` and ``finish`` through.
"""
from __future__ import annotations

from ..registry import SurfaceSpec

__all__ = ["SURFACE", "MIN_SIZE"]


def cartridge(size=2048, **kwargs):
    """See :func:`psbench.forensic.cartridge.make_cartridge`."""
    from .cartridge import make_cartridge  # on use: listing the surfaces stays light

    return make_cartridge(size, **kwargs)


#: ceil(2048 * DEFAULT_PIXEL_SIZE / MAX_PIXEL_SIZE) of psbench.forensic.cartridge: the
#: smallest size at the default field of view whose pixels resolve the marks (tested)
MIN_SIZE = 251

SURFACE = SurfaceSpec(name="cartridge", func=cartridge, aliases=("cartridge_case",),
                      min_size=MIN_SIZE,
                      help="fired cartridge case head (Chapter 7): firing pin, breech-face "
                           "marks, ejector mark, headstamp; gun=, case=, pixel_size= (um)")
