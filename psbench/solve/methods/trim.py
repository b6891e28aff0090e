"""``trim``: per-pixel order statistics -- drop the darkest and brightest observations.

Per pixel, the valid observations are ranked by intensity; the darkest ``drop_dark``
fraction (attached and cast shadows, dark outliers) and the brightest ``drop_bright``
fraction (specular highlights, bright outliers) are dropped, and rho * n is the least
squares solution on the rest. This is the rank-based ("order statistics") rule of
robust photometric stereo: shadows are the darkest and highlights the brightest
observations of a pixel whatever its albedo, so no threshold in intensity units is
needed -- unlike the thesis's Th mask, whose bounds come from each image's range.
It is the trimmed least-squares estimator of robust statistics with the ordering
taken on the observations, not on the residuals, so it needs no starting solution and
no iteration. Its limits: it drops the fractions whatever the data (under noise it
discards good observations and its choice follows the noise), and with few lights
the middle ranks it keeps can be a poorly conditioned set of directions (DiLiGenT
bear, 8 lights 12x4+32x4: 19.0 degrees against 9.5 for least squares).

Sources: the rule of four-source photometric stereo generalised to k images
(E. N. Coleman and R. Jain, "Obtaining 3-dimensional shape of textured and specular
surfaces using four-source photometry", CGIP 18, 1982, drop the brightest of four;
H. Rushmeier, G. Taubin and A. Guéziec, "Applying shape from lighting variation to
bump map capture", EGWR 1997, drop the brightest and the darkest of five); trimmed
least squares: P. J. Rousseeuw and A. M. Leroy, "Robust Regression and Outlier
Detection", Wiley, 1987.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...registry import Method
from ..base import Options, check_number
from ._robust_common import Pixels, wls

__all__ = ["TrimOptions", "trim", "trim_valid", "METHOD"]


@dataclass
class TrimOptions(Options):
    """Options of ``trim`` (plus the mask-engine options of :class:`Options`).

    Parameters
    ----------
    drop_dark : float, default 0.25
        Fraction of each pixel's valid observations dropped from the dark end, in
        [0, 0.5). ``floor(drop_dark * m)`` observations of a pixel with m valid ones.
    drop_bright : float, default 0.25
        Fraction dropped from the bright end, in [0, 0.5).

    Notes
    -----
    At least three observations are always kept (the drops shrink, dark end first,
    where they would leave fewer). Observations equal in intensity to a dropped one
    are dropped with it (a run of zeros in shadow or of saturated values is one
    level), unless that would leave fewer than three, in which case the pixel keeps
    exactly the rank window.
    """

    drop_dark: float = 0.25
    drop_bright: float = 0.25

    def __post_init__(self):
        super().__post_init__()
        check_number(self.drop_dark, "drop_dark", lo=0, hi=0.5, hi_open=True)
        check_number(self.drop_bright, "drop_bright", lo=0, hi=0.5, hi_open=True)


def _counts(m, dark, bright):
    """Per-pixel numbers of dropped dark / bright observations, keeping >= 3."""
    m = np.asarray(m)
    nd = np.floor(dark * m).astype(np.int64)
    nb = np.floor(bright * m).astype(np.int64)
    excess = np.maximum(0, np.minimum(3, m) - (m - nd - nb))
    cut = np.minimum(nd, excess)
    nd = nd - cut
    nb = nb - np.minimum(nb, excess - cut)
    return nd, nb


def trim_valid(px: Pixels, dark: float, bright: float) -> np.ndarray:
    """Observations kept by the rank trimming, (n, k) bool (see :class:`TrimOptions`)."""
    I, V = px.I, px.V
    n, k = I.shape
    if px.all_valid:
        nd, nb = (int(v) for v in _counts(k, dark, bright))
        if nd == 0 and nb == 0:
            return V.copy()
        s = np.sort(I, axis=1)
        if nd and nb:
            keep = I > s[:, nd - 1:nd]
            keep &= I < s[:, k - nb:k - nb + 1]
        elif nd:
            keep = I > s[:, nd - 1:nd]
        else:
            keep = I < s[:, k - nb:k - nb + 1]
        # only a tie with a dropped value can leave fewer than the requested count
        tied = np.zeros(n, dtype=bool)
        if nd:
            tied |= s[:, nd - 1] == s[:, nd]
        if nb:
            tied |= s[:, k - nb - 1] == s[:, k - nb]
        rows = np.flatnonzero(tied)
        short = rows[keep[rows].sum(axis=1) < 3]
        if short.size:
            keep[short] = _rank_window(I[short], V[short], px.m[short], dark, bright)
        return keep
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
    # ties with a dropped value may leave fewer than three: exact rank window there
    short = np.flatnonzero(keep.sum(axis=1) < np.minimum(3, px.m))
    if short.size:
        keep[short] = _rank_window(I[short], V[short], px.m[short], dark, bright)
    return keep


def _rank_window(I, V, m, dark, bright):
    """Exact rank window (ties broken by image order) for a few rows."""
    nd, nb = _counts(m, dark, bright)
    order = np.argsort(np.where(V, I, np.float32(np.inf)), axis=1, kind="stable")
    rank = np.empty_like(order)
    np.put_along_axis(rank, order, np.broadcast_to(np.arange(I.shape[1]), order.shape), 1)
    return V & (rank >= nd[:, None]) & (rank < (m - nb)[:, None])


def trim(problem, options: TrimOptions):
    """Rank-trimmed least squares per pixel (see the module docstring).

    Returns a :class:`~psbench.solve.base.Fit` whose ``valid`` holds the kept
    observations (inlier flags); closed form: 0 iterations, converged.
    """
    px = Pixels(problem)
    keep = trim_valid(px, options.drop_dark, options.drop_bright)
    b, _ = wls(px.I, keep.astype(np.float32), px)
    return px.fit("trim", b, valid=keep, iterations=0, converged=True,
                  info={"kept_fraction": float(keep.sum() / max(px.V.sum(), 1))})


METHOD = Method(
    name="trim", func=trim, options=TrimOptions,
    help="per-pixel rank trimming: drop the darkest and brightest fractions, least "
         "squares on the rest")
