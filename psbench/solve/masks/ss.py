"""SS: self-shadow mask (Eq. 3.7, corrected): valid where s . n > 0.

Eq. 3.7 prints the masked and kept cases inverted; psbench masks where s.n <= 0.
"""
from __future__ import annotations

from ...registry import Mask
from .. import kernel

__all__ = ["ss", "apply", "MASK"]


def ss(b, S):
    """Valid where s_i . b > 0, (k, *P) bool for b (*P, 3)."""
    return kernel.lambert(b, S) > 0


def apply(images, b, ctx):
    """Local normal stage."""
    return ss(b, ctx.S32)


MASK = Mask("SS", "normal", apply, help="self shadows: s.n <= 0 from the current normals (Eq. 3.7)")
