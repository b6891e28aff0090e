"""``l1``: least absolute deviations per pixel, minimise sum_i |I_i - s_i . b|.

The L1 residual is the convex relaxation of counting outliers: its minimiser
interpolates (at least) three observations and ignores how far the others lie, so a
minority of gross outliers (shadows, highlights) barely moves it. Solved by
iteratively reweighted least squares with weights 1 / max(|r_i|, eps * scale),
started from the masked least-squares solution; each pixel stops when its solution
stops moving (per-pixel early stopping, :mod:`psbench.solve.methods.robust._irls`).
Source: the L1 residual minimisation of robust photometric stereo as formulated by
L. Wu, A. Ganesh, B. Shi, Y. Matsushita, Y. Wang and Y. Ma, "Robust photometric stereo
via low-rank matrix completion and recovery", ACCV 2010, and compared in S. Ikehata,
D. Wipf, Y. Matsushita and K. Aizawa, "Robust photometric stereo using sparse
regression", CVPR 2012; IRLS for L1 regression: E. Schlossmacher, "An iterative
technique for absolute deviations curve fitting", JASA 68, 1973.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ....registry import Method
from ...base import check_number
from ._irls import IterOptions, irls, robust_scale
from ._common import Pixels, weights_out

__all__ = ["L1Options", "l1", "METHOD"]


@dataclass
class L1Options(IterOptions):
    """Options of ``l1`` (plus ``tol`` = 1e-4 of
    :class:`~psbench.solve.methods.robust._irls.IterOptions` and the mask-engine options).

    Parameters
    ----------
    n_iter : int, default 300
        Maximum IRLS iterations per pixel (IRLS for L1 converges linearly; the
        stragglers are few pixels, so a high cap costs little).
    eps : float, default 1e-5
        Residuals below ``eps * problem.scale`` (the mean dynamic range) get the same
        weight, which keeps the reweighting finite at the interpolated observations;
        in (0, 0.1].
    inlier_k : float, default 3
        ``Fit.valid`` flags as inliers the observations with |r| <= inlier_k * sigma,
        sigma = 1.4826 * median |r| of the pixel (the L1 fit itself has no scale);
        > 0.
    """

    n_iter: int = 300
    eps: float = 1e-5
    inlier_k: float = 3.0

    def __post_init__(self):
        super().__post_init__()
        check_number(self.eps, "eps", lo=0, lo_open=True, hi=0.1)
        check_number(self.inlier_k, "inlier_k", lo=0, lo_open=True)


def l1(problem, options: L1Options):
    """L1 (least absolute deviations) estimate of rho * n per pixel.

    Returns a :class:`~psbench.solve.base.Fit` with the final IRLS weights (scaled to
    a maximum of 1 per pixel), inlier flags (``inlier_k`` robust sigmas), per-pixel
    iterations and converged flags.
    """
    px = Pixels(problem)
    eps = np.float32(options.eps * px.scale)
    all_valid = px.all_valid

    def update(r, V, st):
        w = np.abs(r)
        np.maximum(w, eps, out=w)
        np.divide(np.float32(1), w, out=w)
        if not all_valid:
            w *= V
        return w

    b, w, its, conv, _ = irls(px, px.start(), update, n_iter=options.n_iter, tol=options.tol)
    r = px.I - b @ px.S32.T
    sigma = robust_scale(r, px.V, all_valid, np.float32(1e-5 * px.scale))
    inlier = px.V & (np.abs(r) <= np.float32(options.inlier_k) * sigma[:, None])
    return px.fit("l1", b, valid=inlier, weights=weights_out(w, px.V), iterations=its,
                  converged=conv, n_iter=options.n_iter)


METHOD = Method(name="l1", func=l1, options=L1Options,
                help="least absolute deviations per pixel (IRLS)")
