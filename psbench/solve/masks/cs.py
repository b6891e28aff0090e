"""CS: cast-shadow mask (Eq. 3.9): valid where i - rho s.n >= k_CS * range."""
from __future__ import annotations

import numpy as np

from ...registry import Mask, Threshold
from .. import kernel
from ..thresholds import COUNTS, TABLE_5_2
from ._shared import lambert_residual

__all__ = ["cs", "apply", "MASK"]

K_CS = Threshold("k_CS", TABLE_5_2["k_CS"], (-10.0, 0.0), counts=COUNTS,
                 help="CS: residual below k_CS of the range is a cast shadow (Eq. 3.9, Table 5.2)")


def cs(images, b, S, rng, k_cs, *, resid=None):
    """Eq. 3.9: valid where i - rho s.n >= k_cs * ``rng`` (broadcastable to the images).

    ``images`` (k, *P), ``b`` (*P, 3); ``resid``: the signed residuals when already known.
    """
    r = kernel.residuals(images, b, S) if resid is None else resid
    return r >= np.float32(k_cs) * rng


def apply(images, b, ctx):
    """Local normal stage (shares the Lambert residual with Hi)."""
    rng, dead = ctx.flat_ranges()
    valid = cs(images, b, ctx.S32, rng, ctx.thresholds["k_CS"],
               resid=lambert_residual(ctx, images, b))
    if dead is not None:
        valid |= dead
    return valid


MASK = Mask("CS", "normal", apply, thresholds=(K_CS,), ranges=True,
            help="cast shadows: observation darker than its Lambert prediction (Eq. 3.9)")
