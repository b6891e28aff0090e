"""``huber``: Huber's M-estimator by IRLS with a per-pixel robust (MAD) scale.

rho(u) = u^2 / 2 for |u| <= 1 and |u| - 1/2 beyond, u = r / (c sigma): quadratic for
small residuals and linear for large ones (convex for a fixed scale); it bounds the
influence of an outlier rather than removing it. IRLS weight
w(u) = min(1, 1 / |u|). Source: P. J. Huber, "Robust estimation of a location
parameter", Ann. Math. Statist. 35, 1964; IRLS as in Holland & Welsch (1977); in
photometric stereo, M-estimators solved by reweighted least squares are the robust
formulation of Y. Quéau, B. Durix, T. Wu, D. Cremers, F. Lauze and J.-D. Durou,
"LED-based photometric stereo: modeling, calibration and numerical solution", JMIV 60,
2018 (see :mod:`psbench.solve.methods.robust._irls` for the loop and the scale).
"""
from __future__ import annotations

from dataclasses import dataclass

from ....registry import Method
from ._irls import MOptions, m_estimate

__all__ = ["HuberOptions", "huber", "METHOD"]

C_DEFAULT = 1.345


@dataclass
class HuberOptions(MOptions):
    """Options of ``huber``: ``c`` (None = 1.345, 95 % Gaussian efficiency),
    ``start`` ("lts"), ``scale`` ("fixed"), ``n_iter`` (100), ``tol`` (1e-3) -- see
    :class:`~psbench.solve.methods.robust._irls.MOptions` --
    plus the mask-engine options of :class:`psbench.solve.base.Options`."""


def huber(problem, options: HuberOptions):
    """Huber M-estimate of rho * n per pixel; Fit.weights are the final IRLS weights,
    Fit.valid the observations with |r| <= c sigma."""
    return m_estimate(problem, options, name="huber", c_default=C_DEFAULT)


METHOD = Method(name="huber", func=huber, options=HuberOptions,
                help="Huber M-estimator (IRLS, per-pixel MAD scale)")
