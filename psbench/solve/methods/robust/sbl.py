"""``sbl``: sparse Bayesian learning of the outliers (Ikehata et al., CVPR 2012).

Per pixel the observations are modelled as I = S b + e + noise: Gaussian noise of
variance lambda = (sigma * scale)^2 and a sparse outlier vector e (shadows,
highlights) with an independent zero-mean Gaussian prior of unknown variance gamma_i
per observation. The gammas are learnt by maximising the marginal likelihood (type-II
maximum likelihood, the sparsity-inducing prior of Tipping's relevance vector
machine): outliers get a large gamma, inliers a gamma -> 0, which approximates the
L0 problem "fit b with as few outliers as possible" far more closely than L1.

With b integrated out under a flat prior, each EM iteration is a weighted least
squares with weights w_i = 1 / (lambda + gamma_i) followed by the EM update
gamma_i <- mu_i^2 + Sigma_ii, where mu_i = gamma_i w_i r_i is the posterior mean of
e_i and Sigma_ii = gamma_i - gamma_i^2 (w_i - w_i^2 s_i^T M^-1 s_i),
M = sum_j w_j s_j s_j^T, its posterior variance -- all closed form per observation
(O(k) per pixel, no k x k matrix), vectorised over pixels, with per-pixel early
stopping (:mod:`psbench.solve.methods.robust._irls`).

Source: S. Ikehata, D. Wipf, Y. Matsushita and K. Aizawa, "Robust photometric stereo
using sparse regression", CVPR 2012 (and TPAMI 36(9), 2014); SBL: M. E. Tipping,
"Sparse Bayesian learning and the relevance vector machine", JMLR 1, 2001; D. Wipf and
B. Rao, "Sparse Bayesian learning for basis selection", IEEE TSP 52(8), 2004.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....registry import Method
from ...base import check_number
from ._irls import IterOptions, irls
from ._common import Pixels, leverage, wls

__all__ = ["SBLOptions", "sbl", "METHOD"]


@dataclass
class SBLOptions(IterOptions):
    """Options of ``sbl`` (plus ``tol`` = 1e-4 of
    :class:`~psbench.solve.methods.robust._irls.IterOptions` and the mask-engine options).

    Parameters
    ----------
    n_iter : int, default 300
        Maximum EM iterations per pixel (EM converges slowly near the optimum; with 100
        about 5 % of DiLiGenT bear's pixels were still moving).
    sigma : float, default 0.01
        Standard deviation of the dense Gaussian noise as a fraction of
        ``problem.scale`` (the images' mean dynamic range); lambda = (sigma * scale)^2.
        Residuals well above sigma become outliers. In (0, 1].
    """

    n_iter: int = 300
    sigma: float = 0.01

    def __post_init__(self):
        super().__post_init__()
        check_number(self.sigma, "sigma", lo=0, lo_open=True, hi=1)


def sbl(problem, options: SBLOptions):
    """SBL estimate of rho * n per pixel (see the module docstring).

    Returns a :class:`~psbench.solve.base.Fit` whose ``weights`` are
    lambda / (lambda + gamma_i) in (0, 1] (1: certain inlier), ``valid`` the
    observations with gamma_i < lambda (weight > 1/2), per-pixel iterations and
    converged flags.
    """
    px = Pixels(problem)
    lam = np.float32((options.sigma * px.scale) ** 2)
    g_floor = np.float32(1e-6) * lam
    V = px.V
    all_valid = px.all_valid
    # gamma_0 uniform: the first solve is (masked) least squares
    g0 = np.full(px.I.shape, np.float32(px.scale ** 2))
    w0 = np.float32(1) / (lam + g0)
    if not all_valid:
        w0 *= V
    b0, _, inv0 = wls(px.I, w0, px, want_inverse=True)

    def update(r, Vw, st):
        g = st["gamma"]
        w = np.float32(1) / (lam + g)
        if not all_valid:
            w *= Vw
        P = w - w * w * leverage(st["inv"], px)   # diagonal of the restricted precision
        sig = g - g * g * P                       # posterior variance of e_i
        mu = g * w * r                            # posterior mean of e_i
        g = mu * mu + sig
        np.maximum(g, g_floor, out=g)
        st["gamma"] = g
        w = np.float32(1) / (lam + g)
        if not all_valid:
            w *= Vw
        return w

    state = {"gamma": g0, "inv": inv0}
    b, w, its, conv, st = irls(px, b0, update, n_iter=options.n_iter, tol=options.tol,
                               state=state, want_inverse=True)
    weights = lam * w
    if not all_valid:
        weights *= V
    return px.fit("sbl", b, valid=V & (st["gamma"] < lam), weights=weights, iterations=its,
                  converged=conv, n_iter=options.n_iter, info={"lambda": float(lam)})


METHOD = Method(name="sbl", func=sbl, options=SBLOptions,
                help="sparse Bayesian learning of sparse outliers (Ikehata et al. 2012)")
