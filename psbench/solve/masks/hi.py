"""Hi: highlight mask (Eq. 3.10): valid where i - rho s.n <= k_Hi * range."""
from __future__ import annotations

import numpy as np

from ...registry import Mask, Threshold
from .. import kernel
from ..thresholds import COUNTS, TABLE_5_2
from ._shared import lambert_residual

__all__ = ["hi", "apply", "MASK"]

K_HI = Threshold("k_Hi", TABLE_5_2["k_Hi"], (0.0, 10.0), counts=COUNTS,
                 help="Hi: residual above k_Hi of the range is a highlight (Eq. 3.10, Table 5.2)")


def hi(images, b, S, rng, k_hi, *, resid=None):
    """Eq. 3.10: valid where i - rho s.n <= k_hi * ``rng`` (broadcastable to the images).

    ``images`` (k, *P), ``b`` (*P, 3); ``resid``: the signed residuals when already known.
    """
    r = kernel.residuals(images, b, S) if resid is None else resid
    return r <= np.float32(k_hi) * rng


def apply(images, b, ctx):
    """Local normal stage (shares the Lambert residual with CS)."""
    rng, dead = ctx.flat_ranges()
    valid = hi(images, b, ctx.S32, rng, ctx.thresholds["k_Hi"],
               resid=lambert_residual(ctx, images, b))
    if dead is not None:
        valid |= dead
    return valid


MASK = Mask("Hi", "normal", apply, thresholds=(K_HI,), ranges=True,
            help="highlights: observation brighter than its Lambert prediction (Eq. 3.10)")
