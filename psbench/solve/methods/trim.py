"""``trim``: per-pixel order statistics -- drop the darkest and brightest observations.

Per pixel, the valid observations are ranked by intensity; the darkest ``drop_dark``
and the brightest ``drop_bright`` fractions of the *redundant* observations (those
beyond the three a solve needs) are dropped -- attached and cast shadows, dark
outliers; specular highlights, bright outliers -- and rho * n is the least-squares
solution on the rest. This is the rank-based ("order statistics") rule of robust
photometric stereo: shadows are the darkest and highlights the brightest observations
of a pixel whatever its albedo, so no threshold in intensity units is needed -- unlike
the thesis's Th mask, whose bounds come from each image's range. It needs no starting
solution.

The intensity order is only a proxy for how far an observation lies from the Lambertian
model: a 3x copy of a dim observation can stay below the brightest ones, and dropping
the darkest observations removes the lights farthest from the normal, so the kept ones
crowd around it. ``refine`` passes (default one) therefore rank again by the absolute
residual of the trimmed fit and keep the same number of observations, those of
smallest |residual| -- a concentration step of least trimmed squares, which cannot
increase the trimmed sum of squares -- and solve again.

Why fractions of m - 3 rather than of m: the three observations that determine rho * n
are never spent, so with few lights the kept set keeps some redundancy. With 8 lights
the fractions of m dropped 2 + 2 and kept 4 observations, whose directions cluster
around the normal (the darkest are the lights farthest from it); a 20 % error in one of
them -- DiLiGenT bear's first 19 images are ~20 % too bright -- then moved the normal by
tens of degrees (bear, 12x4+32x4: 19.0 degrees against 9.5 for least squares). With m - 3
it drops 1 + 1 (10.6 degrees with the refine pass); with 96 lights the difference is
negligible (23 instead of 24 at each end).

Sources: the rule of four-source photometric stereo generalised to k images
(E. N. Coleman and R. Jain, "Obtaining 3-dimensional shape of textured and specular
surfaces using four-source photometry", CGIP 18, 1982, drop the brightest of four;
H. Rushmeier, G. Taubin and A. Guéziec, "Applying shape from lighting variation to
bump map capture", EGWR 1997, drop the brightest and the darkest of five); trimmed
least squares and concentration steps: P. J. Rousseeuw and A. M. Leroy, "Robust
Regression and Outlier Detection", Wiley, 1987; P. J. Rousseeuw and K. Van Driessen,
"Computing LTS regression for large data sets", Data Min. Knowl. Disc. 12, 2006.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...registry import Method
from ..base import Options, check_int, check_number
from ._robust_common import Pixels, _concentrate, wls

__all__ = ["TrimOptions", "trim", "trim_valid", "trim_fit", "METHOD"]


@dataclass
class TrimOptions(Options):
    """Options of ``trim`` (plus the mask-engine options of :class:`Options`).

    Parameters
    ----------
    drop_dark : float, default 0.25
        Fraction of each pixel's redundant valid observations dropped from the dark
        end, in [0, 0.5): ``floor(drop_dark * (m - 3))`` of a pixel with m valid ones.
    drop_bright : float, default 0.25
        Fraction dropped from the bright end, in [0, 0.5).
    refine : int, default 1
        Residual-ranked passes after the intensity-ranked fit (>= 0): each keeps as
        many observations as the trimming did, those of smallest |residual| of the
        previous fit (over all valid observations), and solves again. 0: plain rank
        trimming.

    Notes
    -----
    Observations equal in intensity to a dropped one are dropped with it (a run of
    zeros in shadow or of saturated values is one level), unless that would leave
    fewer than three, in which case the pixel keeps exactly the rank window. Pixels
    with at most three valid observations keep them all.
    """

    drop_dark: float = 0.25
    drop_bright: float = 0.25
    refine: int = 1

    def __post_init__(self):
        super().__post_init__()
        check_number(self.drop_dark, "drop_dark", lo=0, hi=0.5, hi_open=True)
        check_number(self.drop_bright, "drop_bright", lo=0, hi=0.5, hi_open=True)
        check_int(self.refine, "refine", lo=0)


def _counts(m, dark, bright):
    """Per-pixel numbers of dropped dark / bright observations: fractions of the m - 3
    redundant ones (at least three are always kept)."""
    red = np.maximum(np.asarray(m) - 3, 0)
    return (np.floor(dark * red).astype(np.int64), np.floor(bright * red).astype(np.int64))


def trim_valid(px: Pixels, dark: float, bright: float) -> np.ndarray:
    """Observations kept by the rank trimming, (n, k) bool (see :class:`TrimOptions`)."""
    return _trim_keep(px, dark, bright)[0]


def _trim_keep(px: Pixels, dark: float, bright: float):
    """(keep (n, k) bool, kept count (n,) int) of the rank trimming."""
    I, V = px.I, px.V
    n, k = I.shape
    if px.all_valid:
        nd, nb = (int(v) for v in _counts(k, dark, bright))
        h = np.full(n, k - nd - nb)
        if nd == 0 and nb == 0:
            return np.ones((n, k), dtype=bool), h
        s = np.sort(I, axis=1)
        if nd and nb:
            keep = I > s[:, nd - 1:nd]
            keep &= I < s[:, k - nb:k - nb + 1]
        elif nd:
            keep = I > s[:, nd - 1:nd]
        else:
            keep = I < s[:, k - nb:k - nb + 1]
        # only a tie with a dropped value can keep fewer than k - nd - nb
        tied = np.zeros(n, dtype=bool)
        if nd:
            tied |= s[:, nd - 1] == s[:, nd]
        if nb:
            tied |= s[:, k - nb - 1] == s[:, k - nb]
        rows = np.flatnonzero(tied)
        if rows.size:
            h[rows] = np.count_nonzero(keep[rows], axis=1)
        short = rows[h[rows] < 3]
    else:
        m = px.m
        nd, nb = _counts(m, dark, bright)
        s = np.where(V, I, np.float32(np.inf))
        s.sort(axis=1)
        lo = np.take_along_axis(s, np.maximum(nd - 1, 0)[:, None], 1)[:, 0]
        lo[nd == 0] = -np.inf
        hi = np.take_along_axis(s, np.minimum(m - nb, k - 1)[:, None], 1)[:, 0]
        hi[nb == 0] = np.inf
        keep = V & (I > lo[:, None]) & (I < hi[:, None])
        h = np.count_nonzero(keep, axis=1)
        # ties with a dropped value may leave fewer than three
        short = np.flatnonzero(h < np.minimum(3, m))
    if short.size:
        keep[short] = _rank_window(I[short], V[short], px.m[short], dark, bright)
        h[short] = np.count_nonzero(keep[short], axis=1)
    return keep, h


def _rank_window(I, V, m, dark, bright):
    """Exact rank window (ties broken by image order) for a few rows."""
    nd, nb = _counts(m, dark, bright)
    order = np.argsort(np.where(V, I, np.float32(np.inf)), axis=1, kind="stable")
    rank = np.empty_like(order)
    np.put_along_axis(rank, order, np.broadcast_to(np.arange(I.shape[1]), order.shape), 1)
    return V & (rank >= nd[:, None]) & (rank < (m - nb)[:, None])


def trim_fit(px: Pixels, dark: float, bright: float, refine: int):
    """Rank-trimmed least squares followed by ``refine`` residual-ranked passes, block
    by block of pixels.

    Returns
    -------
    b : (n, 3) float32
    keep : (n, k) bool
        Observations of the final solve.
    """
    b = np.empty((px.n, 3), dtype=np.float32)
    keep = np.empty(px.I.shape, dtype=bool)
    for sl in px.blocks():
        sub = px.rows(sl)
        kb, h = _trim_keep(sub, dark, bright)
        bb = wls(sub.I, kb, sub)[0]
        if refine:
            bb, kb = _concentrate(sub, bb, h, refine, kb)
        b[sl], keep[sl] = bb, kb
    return b, keep


def trim(problem, options: TrimOptions):
    """Rank-trimmed least squares per pixel (see the module docstring).

    Returns a :class:`~psbench.solve.base.Fit` whose ``valid`` holds the observations
    of the final solve (inlier flags); closed form: 0 iterations, converged.
    """
    px = Pixels(problem)
    b, keep = trim_fit(px, options.drop_dark, options.drop_bright, options.refine)
    return px.fit("trim", b, valid=keep, iterations=0, converged=True,
                  info={"kept_fraction": float(keep.sum() / max(px.V.sum(), 1))})


METHOD = Method(
    name="trim", func=trim, options=TrimOptions,
    help="per-pixel rank trimming: drop the darkest and brightest fractions, least "
         "squares on the rest, then a pass ranked by residual")
