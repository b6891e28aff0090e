"""``cauchy``: the Cauchy (Lorentzian) M-estimator by IRLS with a per-pixel robust (MAD) scale.

rho(u) = log(1 + u^2) / 2, u = r / (c sigma): redescending influence (an outlier's pull
decreases as it moves away), non-convex but smooth. IRLS weight w(u) = 1 / (1 + u^2).
Source: the Cauchy estimator of robust regression (Holland & Welsch, "Robust
regression using iteratively reweighted least-squares", Commun. Stat. 6, 1977);
in photometric stereo it is the robust estimator of Y. Quéau, T. Wu, F. Lauze,
J.-D. Durou and D. Cremers, "A non-convex variational approach to photometric stereo
under inaccurate lighting", CVPR 2017 (see :mod:`psbench.solve.methods.robust._irls` for
the loop and the scale).
"""
from __future__ import annotations

from dataclasses import dataclass

from ....registry import Method
from ._irls import MOptions, m_estimate

__all__ = ["CauchyOptions", "cauchy", "METHOD"]

C_DEFAULT = 2.385


@dataclass
class CauchyOptions(MOptions):
    """Options of ``cauchy``: ``c`` (None = 2.385, 95 % Gaussian efficiency),
    ``start`` ("lts"), ``scale`` ("fixed"), ``n_iter`` (100), ``tol`` (1e-3) -- see
    :class:`~psbench.solve.methods.robust._irls.MOptions` --
    plus the mask-engine options of :class:`psbench.solve.base.Options`."""


def cauchy(problem, options: CauchyOptions):
    """Cauchy M-estimate of rho * n per pixel; Fit.weights are the final IRLS weights,
    Fit.valid the observations with |r| <= c sigma (weight >= 1/2)."""
    return m_estimate(problem, options, name="cauchy", c_default=C_DEFAULT)


METHOD = Method(name="cauchy", func=cauchy, options=CauchyOptions,
                help="Cauchy M-estimator (IRLS, per-pixel MAD scale)")
