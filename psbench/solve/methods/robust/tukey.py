"""``tukey``: Tukey's biweight M-estimator by IRLS with a per-pixel robust (MAD) scale.

rho(u) = (1 - (1 - u^2)^3) / 6 for |u| < 1 and 1/6 beyond, u = r / (c sigma): hard
redescending -- observations beyond c sigma get weight 0 and no influence at all.
IRLS weight w(u) = (1 - u^2)^2 for |u| < 1, else 0. Non-convex: it needs a robust
start (default: rank trimming followed by least-trimmed-squares concentration
steps). Source: A. E. Beaton and J. W. Tukey,
"The fitting of power series, meaning polynomials, illustrated on band-spectroscopic
data", Technometrics 16, 1974; IRLS as in Holland & Welsch (1977); M-estimation by
reweighted least squares in photometric stereo as in Quéau et al., JMIV 60, 2018 (see
:mod:`psbench.solve.methods.robust.huber`).
"""
from __future__ import annotations

from dataclasses import dataclass

from ....registry import Method
from ._irls import MOptions, m_estimate

__all__ = ["TukeyOptions", "tukey", "METHOD"]

C_DEFAULT = 4.685


@dataclass
class TukeyOptions(MOptions):
    """Options of ``tukey``: ``c`` (None = 4.685, 95 % Gaussian efficiency),
    ``start`` ("lts"), ``scale`` ("fixed"), ``n_iter`` (100), ``tol`` (1e-3) -- see
    :class:`~psbench.solve.methods.robust._irls.MOptions` --
    plus the mask-engine options of :class:`psbench.solve.base.Options`."""


def tukey(problem, options: TukeyOptions):
    """Tukey biweight M-estimate of rho * n per pixel; Fit.weights are the final IRLS
    weights, Fit.valid the observations with |r| < c sigma (weight > 0)."""
    return m_estimate(problem, options, name="tukey", c_default=C_DEFAULT)


METHOD = Method(name="tukey", func=tukey, options=TukeyOptions,
                help="Tukey biweight M-estimator (IRLS, per-pixel MAD scale)")
