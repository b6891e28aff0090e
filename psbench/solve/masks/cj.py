"""CJ: Coleman-Jain four-image mask (Section 3.3.3.1): fuses its own solution.

The maths lives in :func:`psbench.solve.subset.cj`. The observations CJ used are
reported as ``valid``: where exactly three residuals of the fused solution vanish the
fourth was excluded (the smallest-albedo triplet was chosen), otherwise all four.
"Vanish" means ``|r| <= 1e-4 * ctx.scale``; CJ does not declare ``ranges``, so
``ctx.scale`` is 1 (image units) unless another stage of the solve measured the
ranges (weighted masks, FWLSE) -- psbench's rule since its first release, kept so
results do not move.
"""
from __future__ import annotations

import numpy as np

from ...registry import Mask, Threshold
from .. import kernel
from ..subset import CJ_THRESHOLD, cj

__all__ = ["apply", "MASK"]

T_CJ = Threshold("t_CJ", CJ_THRESHOLD, (0.0, 1e6),
                 help="CJ threshold on std/mean of the four triplet albedos")


def apply(images, ctx):
    """Fusing subset stage: ``(b, valid)``."""
    b = np.asarray(cj(images, ctx.S, t_cj=ctx.thresholds["t_CJ"]), dtype=np.float32)
    r = np.abs(kernel.residuals(images, b, ctx.S32))
    small = r <= np.float32(1e-4 * ctx.scale)
    three = small.sum(axis=0) == 3
    valid = np.ones_like(small)
    valid[:, three] = small[:, three]
    return b, valid


MASK = Mask("CJ", "subset", apply, images=(4, 4), thresholds=(T_CJ,), fuses=True,
            help="Coleman-Jain: four triplet solutions averaged or the darkest taken (4 images)")
