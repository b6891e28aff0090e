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

import contextlib
import contextvars
from dataclasses import dataclass

import numpy as np

from ....registry import Method
from ...base import Options, check_int, check_number
from ._common import Pixels
from ._kernel import trim_rows

__all__ = ["TrimOptions", "trim", "trim_valid", "trim_fit", "result", "reuse", "METHOD"]


@dataclass
class TrimOptions(Options):
    """Options of ``trim`` (plus the mask-engine options of :class:`Options`).

    Parameters
    ----------
    drop_dark : float, default 0.25
        Fraction of each pixel's redundant valid observations dropped from the dark
        end, in [0, 0.5): ``round(drop_dark * (m - 3))`` (halves up) of a pixel with m valid ones.
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


def trim_valid(px: Pixels, dark: float, bright: float) -> np.ndarray:
    """Observations kept by the rank trimming, (k, n) bool (see :class:`TrimOptions`)."""
    return trim_fit(px, dark, bright, 0)[1]


def trim_fit(px: Pixels, dark: float, bright: float, refine: int, *, half: bool = False):
    """Rank-trimmed least squares followed by ``refine`` residual-ranked passes (one
    compiled pass per pixel: :func:`._robust_kernel.trim_rows`).

    ``half``: the passes keep floor(m / 2) + 1 observations instead of as many as the
    trimming (least-trimmed-squares concentration steps of ~50 % breakdown).

    Returns
    -------
    b : (n, 3) float32
    keep : (k, n) bool
        Observations of the final solve (images x pixels).
    """
    b = np.empty((px.n, 3), dtype=np.float32)
    keep = np.empty((px.k, px.n), dtype=bool)
    if px.n:
        P = np.linalg.pinv(px.S).astype(np.float32)
        trim_rows(px.Ik, px.kernel_valid(), px.all_valid, px.outer_t, px.S32_t, P,
                  float(dark), float(bright), int(refine), bool(half), b, keep)
    return b, keep


def result(px: Pixels, b, keep):
    """The :class:`~psbench.solve.base.Fit` of ``trim`` from :func:`trim_fit`'s output."""
    n_valid = px.m.sum()
    return px.fit("trim", b, valid=keep, iterations=0, converged=True, kn=True,
                  info={"kept_fraction": float(np.count_nonzero(keep) / max(n_valid, 1))})


#: (problem, Fit) that :func:`trim` returns for that problem with the default options
_REUSE = contextvars.ContextVar("psbench_trim_reuse", default=None)


@contextlib.contextmanager
def reuse(problem, fit):
    """Within the block, ``trim(problem, TrimOptions())`` returns ``fit`` (the caller's
    own trim of the same problem with the default options) instead of computing it
    again: ``robust`` starts its Torrance-Sparrow step, which calls ``trim`` for its
    start, from the trimmed fit it has just computed."""
    token = _REUSE.set((problem, fit))
    try:
        yield
    finally:
        _REUSE.reset(token)


def trim(problem, options: TrimOptions):
    """Rank-trimmed least squares per pixel (see the module docstring).

    Returns a :class:`~psbench.solve.base.Fit` whose ``valid`` holds the observations
    of the final solve (inlier flags); closed form: 0 iterations, converged.
    """
    done = _REUSE.get()
    if done is not None and done[0] is problem and options == TrimOptions():
        return done[1]
    px = Pixels(problem)
    b, keep = trim_fit(px, options.drop_dark, options.drop_bright, options.refine)
    return result(px, b, keep)


METHOD = Method(
    name="trim", func=trim, options=TrimOptions,
    help="per-pixel rank trimming: drop the darkest and brightest fractions, least "
         "squares on the rest, then a pass ranked by residual")
