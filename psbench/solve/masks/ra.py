"""RA: whole-image RANSAC over triplets of images (Section 3.3.3.3).

The maths lives in :func:`psbench.solve.subset.ransac`; ``n_subsets`` (option,
default Eq. 3.11) triplets are drawn with the solve's ``seed``.
"""
from __future__ import annotations

import numpy as np

from ...registry import Mask, Threshold
from ..subset import RA_THRESHOLD, ransac

__all__ = ["apply", "MASK"]

T_RA = Threshold("t_RA", RA_THRESHOLD, (0.0, 10.0),
                 help="RANSAC consensus threshold, fraction of the mean dynamic range")


def apply(images, ctx):
    """Subset stage: each pixel's largest consensus set."""
    return np.asarray(ransac(images, ctx.S, threshold=ctx.thresholds["t_RA"],
                             n_subsets=ctx.options.n_subsets, seed=ctx.seed), dtype=bool)


MASK = Mask("RA", "subset", apply, thresholds=(T_RA,),
            help="RANSAC over image triplets: largest consensus set per pixel (Section 3.3.3.3)")
