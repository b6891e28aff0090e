"""``robust``: psbench's default robust estimator -- model the highlight, reject the rest.

For a user who does not know which robust method to pick. Per pixel it chooses between
two fits of the observations the mask expression allows, by the truncated quadratic
loss

    L = sum_i min(r_i^2, c^2 sigma^2)

(an L0 penalty of c^2 noise variances per outlier; the loss behind least trimmed
squares and Tukey-type hard rejection):

1. **Lambertian, trimmed.** The ``trim`` method with its defaults: per-pixel rank
   trimming of the darkest and brightest observations, then a pass ranked by
   |residual| (a least-trimmed-squares concentration step). It needs no model of the
   highlight and removes gross outliers of any kind.
2. **Lambert + Torrance-Sparrow.** The ``tsfit`` method, started from that trimmed
   solution: per pixel the normal and rho_d, with one specular albedo and lobe width
   for the whole object, fitted by Levenberg-Marquardt to every observation that is
   not clearly a cast shadow -- the highlights are modelled, not discarded (thesis
   Eq. 2.14). Fast settings: no hemisphere-grid start (the trimmed start is good),
   the lobe estimated on 500 pixels, a step tolerance of 1e-3 (0.06 degrees), one
   refinement round of the dark observations.

sigma is the noise level of the stack: 1.4826 times the median |residual| over all
valid observations of the better of the two fits (the lower of the two medians).
Where the model explains a pixel
(specular highlights of one material) its loss is the lower; where observations
depart from it in ways no lobe explains (a corrupted observation, a second material,
interreflections) the trimmed fit, which ignores them, wins. With fewer than 5 images
(the model has 3 unknowns per pixel and needs some redundancy) robust is the trimmed
fit alone.

Why this method -- the choice rule, fixed before measuring: the lowest mean of [mean
NE over DiLiGenT cat and bear with all 96 lights, the 16 lights nearest 30x8+60x8 and
the 8 nearest 12x4+32x4] and [mean NE over 80 synthetic scenes: 5 surfaces x
{45x8, 30x8+60x8} x noise {0, 5, 10, 20} % x {Torrance-Sparrow, Phong}, 128^2, cast
shadows], within 1 s per 96-image DiLiGenT object (measured with
``benchmarks/robust.py``; one setting for all objects):

==========================  ======  =========  =====  ======================
method                      real    synthetic  rule   notes
==========================  ======  =========  =====  ======================
least squares               8.80    10.95      9.88
trim (m - 3, refine 1)      7.60    10.83      9.21
cauchy                      7.25     9.59      8.42
rpca                        7.65     9.93      8.79   ~4 s per object
previous robust (windows)   7.08     9.69      8.39
tsfit, its defaults         6.07     7.58      6.83   ~2-6 s per object
trim -> fast tsfit          5.88     7.96      6.92   this method's TS fit
==========================  ======  =========  =====  ======================

Known weaknesses (measured on the same suite): at 20 % noise every highlight model
loses to least squares (robust ~17.3 degrees against 16.0: the model's extra freedom
fits noise); on Phong-rendered scenes the Gaussian lobe is an approximation (9.1
against 7.0 degrees on Torrance-Sparrow scenes, still the lowest of all methods).

Sources: Torrance-Sparrow fit: :mod:`psbench.solve.methods.tsfit`; rank trimming and
concentration steps: :mod:`psbench.solve.methods.trim` (Rousseeuw & Van Driessen,
Data Min. Knowl. Disc. 12, 2006); truncated quadratic loss as the criterion between
models: P. J. Rousseeuw and A. M. Leroy, "Robust Regression and Outlier Detection",
Wiley, 1987. The combination is psbench's.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from ...registry import Method
from ..base import Options, check_choice, check_int, check_number
from ._robust_common import Pixels
from . import trim as trim_mod
from .trim import TrimOptions, trim_fit

__all__ = ["RobustOptions", "robust", "METHOD", "TS_SETTINGS"]

#: the settings of the Torrance-Sparrow step (see the module docstring)
TS_SETTINGS = dict(start="trim", start_grid=0, refine=1, m_sample=500)
#: fewest images for the Torrance-Sparrow step
MIN_TS_IMAGES = 5


@dataclass
class RobustOptions(Options):
    """Options of ``robust`` (plus the mask-engine options of :class:`Options`).

    Parameters
    ----------
    c : float, default 2.5
        Truncation of the per-pixel loss in noise standard deviations (> 0): an
        observation further than c sigma from a fit costs c^2 sigma^2 whatever its
        residual.
    model : {"ts", "lambert"}, default "ts"
        "ts": choose per pixel between the trimmed Lambertian fit and the
        Torrance-Sparrow fit; "lambert": the trimmed Lambertian fit alone (what
        ``trim`` computes; no model of the highlight).
    n_iter : int, default 100
        Maximum Levenberg-Marquardt iterations per pixel of the Torrance-Sparrow step
        (its ``lm_max_iter``); >= 1.
    tol : float, default 1e-3
        Step tolerance of the Torrance-Sparrow step (its ``lm_tol``: radians of normal
        motion, relative change of the albedos and of m); in (0, 0.1).
    """

    c: float = 2.5
    model: str = "ts"
    n_iter: int = 100
    tol: float = 1e-3

    def __post_init__(self):
        super().__post_init__()
        check_number(self.c, "c", lo=0, lo_open=True)
        check_choice(self.model, ("ts", "lambert"), "model")
        check_int(self.n_iter, "n_iter", lo=1)
        check_number(self.tol, "tol", lo=0, hi=0.1, lo_open=True, hi_open=True)


def ts_predict(directions, power, b, rho_s, m):
    """Lambert + Torrance-Sparrow images of the pixels, (n, k) float32.

    ``b`` (n, 3) = rho_d n; ``rho_s`` and ``m`` floats or (n,) arrays; distant lights
    (k, 3) of power (k,), orthographic view (0, 0, 1): f_i = mu_i [rho_d d_i.n +
    rho_s exp(-m^2 arccos(h_i.n)^2)] where d_i.n > 0, else 0 (thesis Eq. 2.14, as
    :func:`psbench.render` renders it)."""
    d = np.asarray(directions, dtype=np.float64)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    h = d + np.array([0.0, 0.0, 1.0])
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    rho = np.linalg.norm(b, axis=1)
    n = b / np.maximum(rho, 1e-30)[:, None]
    cos = n @ d.astype(np.float32).T                          # (n, k)
    th = np.clip(n @ h.astype(np.float32).T, -1.0, 1.0)
    np.arccos(th, out=th)
    th *= th
    th *= -np.square(np.asarray(m, dtype=np.float32)).reshape(-1, 1)
    np.exp(th, out=th)
    th *= np.asarray(rho_s, dtype=np.float32).reshape(-1, 1)
    f = cos * rho[:, None]
    f += th
    f *= cos > 0
    f *= np.asarray(power, dtype=np.float32).reshape(1, -1)
    return f


def _mad(parts):
    """1.4826 * the median of the absolute residuals gathered in ``parts``."""
    a = np.concatenate(parts) if parts else np.zeros(0, dtype=np.float32)
    return 1.4826 * float(np.median(a)) if a.size else 0.0


def robust(problem, options: RobustOptions):
    """psbench's default robust estimate of rho * n (see the module docstring).

    Returns a :class:`~psbench.solve.base.Fit`: per pixel the chosen fit's solution and
    observations (``weights`` of the Torrance-Sparrow fit where it was chosen, the
    trimmed fit's kept observations elsewhere); ``info``: ``ts_fraction`` (pixels
    that chose the Torrance-Sparrow fit), ``sigma`` (fraction of ``problem.scale``),
    ``rho_s``, ``m`` and the Torrance-Sparrow step's convergence.
    """
    px = Pixels(problem)
    d = TrimOptions()
    b_l, keep = trim_fit(px, d.drop_dark, d.drop_bright, d.refine)
    info = {"model": options.model, "c": options.c}
    if options.model == "lambert" or px.k < MIN_TS_IMAGES or px.n == 0:
        info["ts_fraction"] = 0.0
        return px.fit("robust", b_l, valid=keep, iterations=0, converged=True, info=info,
                      kn=True)
    from .tsfit import TsfitOptions, tsfit

    with warnings.catch_warnings(record=True) as caught, \
            trim_mod.reuse(problem, trim_mod.result(px, b_l, keep)):
        # the Torrance-Sparrow step starts from ``trim``: the fit above, not a second one
        warnings.simplefilter("always", RuntimeWarning)
        ts = tsfit(problem, TsfitOptions(**TS_SETTINGS, lm_max_iter=options.n_iter,
                                         lm_tol=options.tol))
    sel = (slice(None),) if px.full else (px.idx,)
    b_t = np.asarray(ts.b, dtype=np.float32).reshape(-1, 3)[sel]
    w_t = np.asarray(ts.weights, dtype=np.float32).reshape(px.k, -1)[(slice(None),) + sel]
    rho_s, m = ts.info.get("rho_s", 0.0), ts.info.get("m", 1.0)
    if np.ndim(rho_s):
        rho_s = np.asarray(rho_s, dtype=np.float32).reshape(-1)[sel]
    if np.ndim(m):
        m = np.asarray(m, dtype=np.float32).reshape(-1)[sel]

    def pick(v, sl):
        return v[sl] if np.ndim(v) else float(v)
    lay = problem.lights
    power = getattr(lay, "power", None)
    power = np.ones(px.k) if power is None else np.asarray(power, dtype=np.float64)
    # squared residuals of both fits, block by block (the model evaluation is the
    # costly part); sigma from the Torrance-Sparrow fit's used observations
    sq_t = np.empty(px.I.shape, dtype=np.float32)
    sq_l = np.empty(px.I.shape, dtype=np.float32)
    sample_t, sample_l = [], []
    for sl in px.blocks():
        sub = px.rows(sl)
        rt = np.subtract(sub.I, ts_predict(lay.directions, power, b_t[sl], pick(rho_s, sl),
                                           pick(m, sl)), out=sq_t[sl])
        rl = np.subtract(sub.I, b_l[sl] @ px.S32.T, out=sq_l[sl])
        step = max(1, int(sub.I.size // 20000))          # a sample of each block
        sample_t.append(np.abs(rt[sub.V] if not px.all_valid else rt.ravel())[::step])
        sample_l.append(np.abs(rl[sub.V] if not px.all_valid else rl.ravel())[::step])
        np.square(rt, out=rt)
        np.square(rl, out=rl)
        if not px.all_valid:
            rt[~sub.V] = 0.0
            rl[~sub.V] = 0.0
    sigma = max(min(_mad(sample_t), _mad(sample_l)), 1e-6 * px.scale)
    cap = np.float32((options.c * sigma) ** 2)
    loss_t = np.minimum(sq_t, cap, out=sq_t).sum(axis=1)
    loss_l = np.minimum(sq_l, cap, out=sq_l).sum(axis=1)
    del sq_t, sq_l
    use_t = loss_t <= loss_l
    b = np.where(use_t[:, None], b_t, b_l)
    weights = np.where(use_t[None, :], w_t, keep.astype(np.float32))   # (k, n)
    conv_t = np.asarray(ts.converged, dtype=bool)
    conv_t = conv_t.reshape(-1)[sel] if conv_t.ndim else np.full(px.n, bool(conv_t))
    it_t = np.asarray(ts.iterations).reshape(-1)[sel] if np.ndim(ts.iterations) else \
        np.full(px.n, int(ts.iterations))
    conv = np.where(use_t, conv_t, True)
    its = np.where(use_t, it_t, 0)
    info.update(ts_fraction=float(use_t.mean()), sigma=sigma / px.scale,
                rho_s=rho_s if not np.ndim(rho_s) else float(np.median(rho_s)),
                m=m if not np.ndim(m) else float(np.median(m)))
    msgs = [str(w.message) for w in caught if not str(w.message).startswith("tsfit:")]
    for msg in msgs:
        warnings.warn(msg, RuntimeWarning, stacklevel=2)
    return px.fit("robust", b, weights=weights, valid=weights > 0, iterations=its,
                  converged=conv, n_iter=options.n_iter, info=info, kn=True)


METHOD = Method(name="robust", func=robust, options=RobustOptions,
                help="default robust choice: per pixel, the better (truncated loss) of a "
                     "trimmed Lambertian fit and a Lambert + Torrance-Sparrow fit")
