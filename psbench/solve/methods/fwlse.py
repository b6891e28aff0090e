"""fwlse: feasible weighted least squares (Section 3.4.1), started from the masked
least-squares solution; the maths is :func:`psbench.solve.weighted.fwlse`."""
from __future__ import annotations

from dataclasses import dataclass

from ...registry import Method
from ..base import Fit, Options, check_number
from ..weighted import fwlse as _fwlse

__all__ = ["FWLSEOptions", "fwlse", "METHOD"]


@dataclass
class FWLSEOptions(Options):
    """Options of "fwlse": the mask engine's (:class:`psbench.solve.base.Options`) plus

    Parameters
    ----------
    fwlse_tol : float
        Stop when the largest change of a variance between two iterations is below
        ``fwlse_tol * R^2`` (R = mean dynamic range); > 0, default 1e-3. ``max_iter``
        bounds the iterations (at least 1). ``sigma_min`` (None = 1 % of R) is the
        smallest standard deviation.
    """

    fwlse_tol: float = 1e-3

    needs_ranges = True  # reads problem.scale

    def __post_init__(self):
        super().__post_init__()
        check_number(self.fwlse_tol, "fwlse_tol", lo=0, lo_open=True)


def fwlse(problem, options):
    """Iterate WLS with weights valid_i / max(|r_i|, sigma_min)^2 (Section 3.4.1)."""
    valid = problem.valid
    scale = problem.scale
    smin = options.sigma_min if options.sigma_min is not None else 0.01 * scale
    b, weights, it, conv = _fwlse(problem.images, problem.S, problem.start(),
                                  None if valid.all() else valid, sigma_min=smin,
                                  tol=options.fwlse_tol, max_iter=max(1, options.max_iter),
                                  scale=scale)
    return Fit(b=b, weights=weights, iterations=it, converged=conv,
               info={"fwlse_iterations": it, "converged": conv})


METHOD = Method("fwlse", fwlse, options=FWLSEOptions, masked=True,
                help="feasible weighted least squares from the masked solution (Section 3.4.1)")
