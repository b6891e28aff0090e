"""``rpca``: low-rank + sparse decomposition of the observation matrix (Wu et al. 2010).

Stack the object pixels' observations into D (n pixels x k images). A Lambertian
object without shadows gives rank(D) <= 3 (D = B S^T); shadows, highlights and other
non-Lambertian effects are sparse errors E. Robust PCA recovers both,

    min ||A||_* + lam ||E||_1   subject to  P_Omega(D) = P_Omega(A + E),

where Omega holds the observations the mask kept (the others are missing entries and
are completed by the low-rank part: matrix completion and recovery at once). Solved
by the inexact augmented Lagrange multiplier method: alternate soft-thresholding of E
(on Omega; off Omega E absorbs everything), singular value thresholding of A (at most
``rank`` components kept: the rank-3 Lambertian part) and a multiplier step, with the
penalty growing by ``rho`` per iteration. The singular vectors come from the k x k
Gram matrix of the current estimate (one matrix product over the pixels per
iteration). Unlike the per-pixel methods, RPCA couples all pixels (the common
low-rank structure), so it iterates on the whole matrix and stops when
||P_Omega(D - A - E)||_F <= tol ||P_Omega(D)||_F. Finally rho * n is the least squares
solution of each pixel's row of A with the known lights.

Sources: L. Wu, A. Ganesh, B. Shi, Y. Matsushita, Y. Wang and Y. Ma, "Robust
photometric stereo via low-rank matrix completion and recovery", ACCV 2010;
inexact ALM: Z. Lin, M. Chen and Y. Ma, "The augmented Lagrange multiplier method for
exact recovery of corrupted low-rank matrices", UIUC tech. rep. UILU-ENG-09-2215,
2009 (arXiv:1009.5055); lam = 1 / sqrt(max(n, k)): E. Candès, X. Li, Y. Ma and
J. Wright, "Robust principal component analysis?", J. ACM 58(3), 2011.

Needs at least 4 images (with 3 the rank-3 part explains any data) and a dense set of
observations missing at random: completion fails where a mask removes a systematic
part of the data (the literal Th drops the brightest ~40-50 % of every DiLiGenT image
and ~75 % on small synthetic scenes). Two checks catch it: the recovered part has rank
< 3, or its normals fit the observations worse than least squares (larger median
|residual|); rpca then warns and returns the masked least-squares solution
(``info["fallback"]``).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ...._shared.checks import PsbenchError
from ....registry import Method
from ...base import Options, check_int, check_number
from ._irls import robust_scale
from ._common import Pixels

__all__ = ["RPCAOptions", "rpca", "default_lam", "METHOD", "MIN_IMAGES"]

#: fewest images rpca accepts
MIN_IMAGES = 4


@dataclass
class RPCAOptions(Options):
    """Options of ``rpca`` (plus the mask-engine options of :class:`Options`).

    Parameters
    ----------
    rank : int or None, default 3
        Most singular components kept in the low-rank part (3: Lambertian); None:
        the plain nuclear-norm solution (whatever rank the thresholding leaves).
    lam : float or None, default None
        Weight of ||E||_1; None: :func:`default_lam` (1 / sqrt(max(n, k)) for an
        n-pixel, k-image matrix, raised to the coherence level of D's rank-r part
        where that is higher, as for small k). > 0.
    n_iter : int, default 200
        Maximum ALM iterations (>= 1).
    tol : float, default 1e-5
        Stop when the constraint residual is at most ``tol`` relative to ||D||; in
        (0, 1).
    rho : float, default 1.2
        Growth factor of the penalty mu per iteration, > 1 (Lin et al. use 1.5; the
        slower growth lets the sparse part settle before the constraint is forced,
        which recovers 20 %-corrupted 16-image stacks that 1.5 does not).
    inlier_k : float, default 3
        ``Fit.valid`` flags as inliers the observations with
        |E| <= inlier_k * 1.4826 * median |E| of the pixel; > 0.
    """

    min_images: ClassVar[int] = MIN_IMAGES

    rank: int | None = 3
    lam: float | None = None
    n_iter: int = 200
    tol: float = 1e-5
    rho: float = 1.2
    inlier_k: float = 3.0

    def __post_init__(self):
        super().__post_init__()
        if self.rank is not None:
            check_int(self.rank, "rank", lo=1)
        check_number(self.lam, "lam", lo=0, lo_open=True, allow_none=True)
        check_int(self.n_iter, "n_iter", lo=1)
        check_number(self.tol, "tol", lo=0, lo_open=True, hi=1, hi_open=True)
        check_number(self.rho, "rho", lo=1, lo_open=True)
        check_number(self.inlier_k, "inlier_k", lo=0, lo_open=True)


def _top_subspace(X, Q, power=1):
    """Warm-started subspace iteration: orthonormal (k, q) basis of the dominant right
    singular subspace of X (n, k), refined from the previous basis Q."""
    for _ in range(power):
        Q, _ = np.linalg.qr((X.T @ (X @ Q)).astype(np.float64))
        Q = Q.astype(np.float32)
    return Q


def _svt(X, tau, rank, Q=None):
    """Singular value thresholding of a tall X (n, k) at ``tau`` keeping at most
    ``rank`` components.

    With a rank cap the dominant subspace comes from one warm-started subspace
    iteration on the basis ``Q`` (rank + 2 columns, returned refined); otherwise from
    the eigen-decomposition of the k x k Gram matrix. Returns (A, kept rank, Q).
    """
    if rank is not None and Q is not None:
        Q = _top_subspace(X, Q)
        B = X @ Q                                         # (n, q)
        ev, W = np.linalg.eigh((B.T @ B).astype(np.float64))
        s = np.sqrt(np.maximum(ev[::-1], 0.0))
        W = W[:, ::-1]
        keep = min(int((s > tau).sum()), rank)
        if keep == 0:
            return np.zeros_like(X), 0, Q
        Wr = W[:, :keep]
        f = (s[:keep] - tau) / s[:keep]
        # A = X V diag(f) V^T with V = Q W_r
        Vr = (Q @ Wr).astype(np.float32)
        return (B @ (Wr * f).astype(np.float32)) @ Vr.T, keep, Q
    G = (X.T @ X).astype(np.float64)
    ev, Vk = np.linalg.eigh(G)
    s = np.sqrt(np.maximum(ev[::-1], 0.0))
    Vk = Vk[:, ::-1]
    keep = int((s > tau).sum())
    if rank is not None:
        keep = min(keep, rank)
    if keep == 0:
        return np.zeros_like(X), 0, Q
    Vr = Vk[:, :keep]
    f = (s[:keep] - tau) / s[:keep]
    # A = U diag(s - tau) V^T = X V diag((s - tau) / s) V^T
    P = ((Vr * f) @ Vr.T).astype(np.float32)
    return X @ P, keep, Q


def default_lam(D, V, s, rank):
    """Default weight of ||E||_1: max(1 / sqrt(max(n, k)), q99 |U_r V_r^T|).

    The first term is the universal choice of Candès et al. (2011). Exact recovery of
    a clean low-rank D = U S V^T needs lam >= ||U V^T||_inf (then U V^T certifies
    E = 0 as optimal). Photometric stereo matrices are very tall (n pixels >> k
    images) and for small k that level exceeds 1 / sqrt(n), so even clean Lambertian
    data would leak into E; the second term, the 99th percentile of |U_r V_r^T| of
    the rank-r approximation of D (the percentile ignores the few rows made coherent
    by outliers), keeps lam above it. ``V`` (k, r) and ``s`` (r,) are D's leading
    right singular vectors and values.
    """
    n, k = D.shape
    lam = 1.0 / np.sqrt(max(n, k))
    keep = s > 0
    if keep.any():
        U = (D @ V[:, keep].astype(np.float32)) / s[keep].astype(np.float32)
        M = np.abs(U @ V[:, keep].T.astype(np.float32))
        lam = max(lam, float(np.percentile(M, 99)))
    return lam


def rpca(problem, options: RPCAOptions):
    """RPCA estimate of rho * n (see the module docstring).

    Returns a :class:`~psbench.solve.base.Fit` with inlier flags ``valid`` (small
    sparse error), the ALM iteration count (one for all pixels) and ``converged``.
    """
    k = problem.images.shape[0]
    if k < MIN_IMAGES:
        raise PsbenchError(f"method 'rpca' needs at least {MIN_IMAGES} images, got {k}")
    px = Pixels(problem)
    n = px.n
    V = px.V
    D = np.where(V, px.I, np.float32(0))
    norm_d = float(np.linalg.norm(D))
    if norm_d == 0.0:
        return px.fit("rpca", np.zeros((n, 3), np.float32), valid=V, iterations=0,
                      converged=True, info={"rank": 0})
    ev, Vk = np.linalg.eigh((D.T @ D).astype(np.float64))
    norm_two = float(np.sqrt(max(ev[-1], 0.0)))
    Q = None
    if options.rank is not None:
        q = min(k, options.rank + 2)
        Q = np.ascontiguousarray(Vk[:, ::-1][:, :q], dtype=np.float32)
    r0 = 3 if options.rank is None else min(options.rank, k)
    lead = Vk[:, ::-1][:, :r0]
    lam = np.float32(options.lam if options.lam is not None else
                     default_lam(D, lead, np.sqrt(np.maximum(ev[::-1][:r0], 0.0)), r0))
    Y = D / np.float32(max(norm_two, float(np.abs(D).max()) / lam))
    A = np.zeros_like(D)
    E = np.zeros_like(D)
    mu = 1.25 / norm_two
    mu_bar = mu * 1e7
    missing = None if px.all_valid else ~V
    converged, it, rank, crit = False, 0, 0, np.inf
    for it in range(1, options.n_iter + 1):
        T = D - A
        T += Y * np.float32(1.0 / mu)
        # E: soft threshold on the observed entries (T - clip(T)), free on the missing
        E = np.clip(T, -np.float32(lam / mu), np.float32(lam / mu))
        np.subtract(T, E, out=E)
        if missing is not None:
            E[missing] = T[missing]
        T += A
        T -= E                   # = D - E + Y / mu
        A, rank, Q = _svt(T, 1.0 / mu, options.rank, Q)
        Z = D - A
        Z -= E
        Y += np.float32(mu) * Z
        crit = float(np.linalg.norm(Z)) / norm_d
        mu = min(mu * options.rho, mu_bar)
        if crit <= options.tol:
            converged = True
            break
    info = {"rank": int(rank), "lam": float(lam), "residual": crit}
    if rank < min(3, k):
        # the observations do not determine a rank-3 part (e.g. a mask left too few
        # per pixel for matrix completion): say so and use masked least squares
        msg = (f"rpca: the low-rank part has rank {rank} < 3 (observed fraction "
               f"{V.mean():.0%}); falling back to masked least squares")
        warnings.warn(msg, RuntimeWarning, stacklevel=2)
        info["warnings"] = [msg]
        info["fallback"] = "ls"
        return px.fit("rpca", px.start(), valid=V, iterations=it, converged=False,
                      n_iter=options.n_iter, info=info)
    P = np.linalg.pinv(px.S).astype(np.float32)
    b = A @ P.T
    # sanity check: with only sparse outliers the low-rank fit explains the bulk (the
    # median) of the observations at least as well as least squares does; when it does
    # not, completion failed (e.g. a mask removed a systematic half of the data)
    med = float(np.median(np.abs(px.I - b @ px.S32.T)[V]))
    b_ls = px.start()
    med_ls = float(np.median(np.abs(px.I - b_ls @ px.S32.T)[V]))
    info["median_residual"], info["median_residual_ls"] = med, med_ls
    if med > med_ls:
        msg = (f"rpca: the decomposition fits the observations worse than least squares "
               f"(median |residual| {med:.3g} > {med_ls:.3g}, observed fraction "
               f"{V.mean():.0%}); falling back to masked least squares")
        warnings.warn(msg, RuntimeWarning, stacklevel=2)
        info["warnings"] = [msg]
        info["fallback"] = "ls"
        return px.fit("rpca", b_ls, valid=V, iterations=it, converged=False,
                      n_iter=options.n_iter, info=info)
    Eo = np.where(V, E, np.float32(0))
    sigma = robust_scale(Eo, V, px.all_valid, np.float32(1e-5 * px.scale))
    inlier = V & (np.abs(Eo) <= np.float32(options.inlier_k) * sigma[:, None])
    return px.fit("rpca", b, valid=inlier, iterations=it, converged=converged,
                  n_iter=options.n_iter, info=info)


METHOD = Method(name="rpca", func=rpca, options=RPCAOptions,
                help="robust PCA: rank-3 + sparse decomposition, inexact ALM (Wu et al. 2010)")
