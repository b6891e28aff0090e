"""``robust``: psbench's default robust estimator -- shadows are dark, highlights bright.

For a user who does not know which robust method to pick. Per pixel it minimises the
truncated quadratic loss

    sum_i min(r_i^2, c^2 sigma^2),      r_i = I_i - s_i . b,

i.e. least squares in which an observation may be declared an outlier at a fixed cost
of c^2 (an L0 penalty on the number of outliers, the loss behind Tukey-type hard
rejection), in two stages:

1. **Rank windows (global search).** Shadows are a pixel's darkest observations and
   highlights its brightest, whatever its albedo, so the outliers of a photometric
   stereo pixel are mostly at the two ends of its intensity order. Restricted to
   "drop the a darkest and the b brightest", the loss is minimised *exactly*: every
   window (a, b) on a grid up to ``max_drop`` of the valid observations at each end is
   solved at once from cumulative sums of s s^T, I s and I^2 along the sorted order
   (O(k) per window, no iteration, no starting point, no local minimum).
2. **Concentration steps (local).** From that solution, alternate: inliers = the
   observations with |r| <= c sigma (any rank), least squares on them; each step
   cannot increase the loss and the loop stops when the inlier set is stable
   (Rousseeuw & Van Driessen's C-steps). This catches outliers inside the order
   (a corrupted mid-tone, a cast shadow on a bright light).

sigma is the noise level of the image stack, estimated once from the data (not per
pixel): 1.4826 times the median over the object of each pixel's median absolute
residual of the rank-trimmed fit (25 % dark / 25 % bright dropped). With the noise
level known, an observation is dropped only when it costs more than c^2 noise
variances to keep -- noiseless data are fitted exactly, noisy data keep their
observations (least squares efficiency), and gross errors go.

Why this method (measured with ``benchmarks/robust.py`` and a synthetic suite, one
setting for all; the choice rule, fixed beforehand: the lowest mean of [mean NE over
the real cases] and [mean NE over the synthetic scenes]):

=====================  =========================  ==============================
method                 DiLiGenT cat/bear, 96 and  60 synthetic scenes (5 surfaces,
                       16 lights (mean of 4)      45x8/45x16/30x8+60x8, 0-20 % noise)
=====================  =========================  ==============================
least squares          8.66                       10.36
trim (25 %/25 %)       7.02                       10.65
l1                     7.34                       10.25
cauchy                 7.04                       9.23
tukey                  6.68                       9.27
sbl                    6.68                       10.80
rpca                   7.07                       8.95
robust (c = 2.5)       6.67                       8.94
robust with c = 2      6.44                       9.16
=====================  =========================  ==============================

(c = 2 and 2.5 tie on the rule -- 7.80 and 7.81 -- and the conventional 2.5 of
reweighted least trimmed squares is kept.) Fixed-fraction trimming collapses under
noise and with 8 lights (it keeps the middle ranks whatever they are);
residual-based estimators keep broad highlight lobes; RPCA is as good on the
synthetic scenes but weaker on real 16-light data and takes ~2 s for 96 DiLiGenT
images (budget: 1 s). Known weaknesses: robust is worse than least squares on 24 of
the 60 synthetic scenes, at 20 % noise and on noiseless Torrance-Sparrow scenes with
broad highlight lobes (sombrero2 under 30x8+60x8: 7.8 vs 6.8 degrees), where each
observation's highlight excess stays within the estimated noise level; RPCA, which
pools all pixels, does better there.

Sources: truncated quadratic / hard-rejection loss and concentration steps:
P. J. Rousseeuw and K. Van Driessen, "Computing LTS regression for large data sets",
Data Min. Knowl. Disc. 12, 2006; order statistics of the intensities to exclude
shadows and highlights: Coleman & Jain (CGIP 18, 1982), Rushmeier, Taubin & Guéziec
(EGWR 1997) (see :mod:`psbench.solve.methods.trim`); the combination (exhaustive
search over rank windows with a noise-calibrated L0 penalty) is psbench's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...registry import Method
from ..base import check_number
from ._irls import IterOptions, irls
from ._robust_common import Pixels, masked_median, wls
from .trim import trim_valid

__all__ = ["RobustOptions", "robust", "noise_sigma", "window_search", "METHOD"]

#: pixels per chunk of the window search (bounds its float64 temporaries)
_CHUNK_VALUES = 1 << 21


@dataclass
class RobustOptions(IterOptions):
    """Options of ``robust`` (plus ``n_iter`` = 100 concentration steps at most and
    ``tol`` = 1e-4 of :class:`~psbench.solve.methods._irls.IterOptions`, and the
    mask-engine options).

    Parameters
    ----------
    c : float, default 2.5
        Outlier cutoff in noise standard deviations: dropping an observation costs
        c^2 noise variances; > 0.
    sigma : float or None, default None
        Noise standard deviation as a fraction of ``problem.scale`` (the images'
        mean dynamic range); None: estimated from the data (see the module
        docstring). In (0, 1].
    max_drop : float, default 0.45
        Largest fraction of a pixel's valid observations the window search may drop
        at each end, in [0, 0.5).
    """

    c: float = 2.5
    sigma: float | None = None
    max_drop: float = 0.45

    def __post_init__(self):
        super().__post_init__()
        check_number(self.c, "c", lo=0, lo_open=True)
        check_number(self.sigma, "sigma", lo=0, lo_open=True, hi=1, allow_none=True)
        check_number(self.max_drop, "max_drop", lo=0, hi=0.5, hi_open=True)


def noise_sigma(px: Pixels, b, floor):
    """Noise level of the stack: 1.4826 * median over pixels of each pixel's median
    |residual| of the solution ``b`` over its valid observations (>= ``floor``)."""
    r = np.abs(px.I - b @ px.S32.T)
    med = masked_median(r, px.V, px.m, px.all_valid)
    return max(float(np.median(med)) * 1.4826, floor) if med.size else floor


def _grid(max_count, m_max):
    """Drop counts tried at each end: 0..max_count, at most 11 values."""
    step = max(1, -(-max_count // 10))
    return np.arange(0, max_count + 1, step)


def window_search(px: Pixels, sigma, c, max_drop):
    """Stage 1: exact minimiser of the truncated loss over rank windows.

    Returns
    -------
    b : (n, 3) float32
    drops : (n, 2) int
        Dark and bright counts of each pixel's window.
    """
    I, V = px.I, px.V
    n, k = I.shape
    counts = _grid(int(np.floor(max_drop * k)), k)
    A, B = np.meshgrid(counts, counts, indexing="ij")
    A, B = A.ravel(), B.ravel()
    sel = k - A - B >= min(k, 4)
    A, B = A[sel], B[sel]
    nw = A.size
    pen = ((float(c) * float(sigma)) ** 2 * (A + B))[:, None]   # intensity^2 units
    S = px.S
    outer = px.outer.astype(np.float64)
    b_out = np.empty((n, 3), dtype=np.float32)
    drops = np.zeros((n, 2), dtype=np.int32)
    p = int(min(n, max(128, _CHUNK_VALUES // (10 * (nw + k + 1))))) if n else 0
    # buffers reused across chunks (fresh multi-megabyte temporaries cost page faults)
    G = np.zeros((k + 1, 10, p))
    Wsum = np.empty((nw, 10, p))
    t1, t2, q, den = (np.empty((nw, p)) for _ in range(4))
    pos = np.arange(k)
    for lo in range(0, n, p):
        hi = min(n, lo + p)
        pc = hi - lo
        if pc < p:  # last chunk: views of the buffers
            G, Wsum = G[:, :, :pc], Wsum[:, :, :pc]
            t1, t2, q, den = t1[:, :pc], t2[:, :pc], q[:, :pc], den[:, :pc]
        Ic = I[lo:hi]
        if px.all_valid:
            order = np.argsort(Ic, axis=1)
        else:
            m = px.m[lo:hi]
            order = np.argsort(np.where(V[lo:hi], Ic, np.float32(np.inf)), axis=1)
        # per sorted position j: the 6 entries of s s^T, I s and I^2, summed cumulatively
        # along the order; in the (k + 1, 10, p) layout every window sum is the
        # difference of two contiguous (10, p) blocks
        oT = order.T
        IsT = np.take_along_axis(Ic, order, 1).T.astype(np.float64)   # (k, p)
        F = G[1:]
        for j in range(6):
            F[:, j, :] = outer[:, j][oT]
        for j in range(3):
            np.multiply(IsT, S[:, j][oT], out=F[:, 6 + j, :])
        np.multiply(IsT, IsT, out=F[:, 9, :])
        if not px.all_valid:
            F *= (pos[:, None] < m[None, :])[:, None, :]           # invalid sorted last
        np.cumsum(F, axis=0, out=F)
        if px.all_valid:
            for w in range(nw):
                np.subtract(G[k - B[w]], G[A[w]], out=Wsum[w])
            ok = np.ones((nw, pc), dtype=bool)
        else:
            top = np.clip(m[None, :] - B[:, None], 0, k)            # (W, p)
            lim = np.floor(max_drop * m)[None, :]
            ok = ((m[None, :] - B[:, None] - A[:, None] >= np.minimum(m, 4)[None, :])
                  & (A[:, None] <= lim) & (B[:, None] <= lim))
            cols = np.arange(pc)
            for w in range(nw):
                np.subtract(G[top[w], :, cols].T, G[A[w]], out=Wsum[w])
        a00, a01, a02, a11, a12, a22 = (Wsum[:, j, :] for j in range(6))
        r0, r1, r2 = Wsum[:, 6, :], Wsum[:, 7, :], Wsum[:, 8, :]
        # rss = I.I - r^T adj(M) r / det(M): the windows' solutions are not needed
        c00 = a11 * a22 - a12 * a12
        c01 = a02 * a12 - a01 * a22
        c02 = a01 * a12 - a02 * a11
        np.multiply(a00, c00, out=den)
        np.multiply(a01, c01, out=t1)
        den += t1
        np.multiply(a02, c02, out=t1)
        den += t1                                                   # det
        np.multiply(c00, r0, out=q)
        np.multiply(c01, r1, out=t1)
        q += t1
        np.multiply(c02, r2, out=t1)
        q += t1
        q *= r0                                                     # r0 (adj r)_0
        c11 = a00 * a22 - a02 * a02
        c12 = a01 * a02 - a00 * a12
        np.multiply(c01, r0, out=t1)
        np.multiply(c11, r1, out=t2)
        t1 += t2
        np.multiply(c12, r2, out=t2)
        t1 += t2
        t1 *= r1
        q += t1                                                     # + r1 (adj r)_1
        c22 = a00 * a11 - a01 * a01
        np.multiply(c02, r0, out=t1)
        np.multiply(c12, r1, out=t2)
        t1 += t2
        np.multiply(c22, r2, out=t2)
        t1 += t2
        t1 *= r2
        q += t1                                                     # + r2 (adj r)_2
        np.add(a00, a11, out=t2)
        t2 += a22
        np.power(t2, 3, out=t2)
        t2 *= 1e-9
        ok &= np.abs(den) > t2
        np.divide(q, den, out=q, where=ok)
        np.subtract(Wsum[:, 9, :], q, out=q)                        # rss
        np.maximum(q, 0.0, out=q)
        q += pen
        q[~ok] = np.inf
        jw = np.argmin(q, axis=0)
        cols = np.arange(pc)
        good = ok[jw, cols]
        cj = [cc[jw, cols] for cc in (c00, c01, c02, c11, c12, c22)]
        rj = [rr[jw, cols] for rr in (r0, r1, r2)]
        inv = 1.0 / np.where(good, den[jw, cols], 1.0)
        b_out[lo:hi, 0] = (cj[0] * rj[0] + cj[1] * rj[1] + cj[2] * rj[2]) * inv
        b_out[lo:hi, 1] = (cj[1] * rj[0] + cj[3] * rj[1] + cj[4] * rj[2]) * inv
        b_out[lo:hi, 2] = (cj[2] * rj[0] + cj[4] * rj[1] + cj[5] * rj[2]) * inv
        drops[lo:hi, 0] = A[jw]
        drops[lo:hi, 1] = B[jw]
        if not good.all():  # no usable window (degenerate lights): masked least squares
            bad = lo + np.flatnonzero(~good)
            b_out[bad] = wls(I[bad], V[bad].astype(np.float32), px)[0]
            drops[bad] = 0
    return b_out, drops


def robust(problem, options: RobustOptions):
    """psbench's default robust estimate of rho * n (see the module docstring).

    Returns a :class:`~psbench.solve.base.Fit` whose ``valid`` holds the final
    inliers (|r| <= c sigma), per-pixel concentration-step counts and converged
    flags; ``info`` has the noise level ``sigma`` (fraction of ``problem.scale``)
    and the mean drop counts of the window stage.
    """
    px = Pixels(problem)
    floor = 1e-6 * px.scale
    if options.sigma is None:
        keep = trim_valid(px, 0.25, 0.25)
        b_trim = wls(px.I, keep.astype(np.float32), px)[0]
        sigma = noise_sigma(px, b_trim, floor)
    else:
        sigma = options.sigma * px.scale
    b0, drops = window_search(px, sigma, options.c, options.max_drop)
    thr = np.float32(options.c * sigma)
    all_valid = px.all_valid

    def update(r, V, st):
        w = (np.abs(r) <= thr).astype(np.float32)
        if not all_valid:
            w *= V
        return w

    b, w, its, conv, _ = irls(px, b0, update, n_iter=options.n_iter, tol=options.tol)
    inlier = w > 0
    return px.fit("robust", b, valid=inlier, iterations=its, converged=conv,
                  n_iter=options.n_iter,
                  info={"sigma": sigma / px.scale, "c": options.c,
                        "mean_dropped_dark": float(drops[:, 0].mean()) if px.n else 0.0,
                        "mean_dropped_bright": float(drops[:, 1].mean()) if px.n else 0.0})


METHOD = Method(name="robust", func=robust, options=RobustOptions,
                help="default robust choice: noise-calibrated outlier rejection over "
                     "dark/bright rank windows, then concentration steps")
