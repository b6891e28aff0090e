"""xNL: extended non-Lambert quadruples for k >= 4 images (Section 3.3.3.2).

The maths (sorted consecutive quadruples, pattern runs, reflection-corrected broken
patterns) lives in :func:`psbench.solve.subset.xnl`. With a multi-ring layout t_Re
differs per light; xNL takes one angle, the smallest.
"""
from __future__ import annotations

import numpy as np

from ...registry import Mask
from ..subset import xnl
from ._shared import T_NL, T_RE

__all__ = ["apply", "MASK"]


def apply(images, ctx):
    """Subset stage: per-pixel validity of the chosen Lambertian run."""
    t_re = float(ctx.t_re().min())
    return np.asarray(xnl(images, ctx.S, t_nl=ctx.thresholds["t_NL"], t_re=t_re), dtype=bool)


MASK = Mask("xNL", "subset", apply, images=(4, None), thresholds=(T_NL, T_RE),
            help="sorted consecutive quadruples for k >= 4 images (Section 3.3.3.2)")
