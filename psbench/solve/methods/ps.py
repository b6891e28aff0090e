"""ps: masked least squares -- the solution the mask engine already computed."""
from __future__ import annotations

from ...registry import Method
from ..base import Fit, Options

__all__ = ["ps", "METHOD"]


def ps(problem, options):
    """Least squares over the observations the mask expression kept (Eq. 2.17 with 0/1
    weights; Fig. 3.1 steps 5-6 with normal masks)."""
    return Fit(b=problem.start())


METHOD = Method("ps", ps, options=Options, masked=True,
                help="masked least squares (the thesis's unified PS)")
