"""``tsfit``: per-pixel fit of Lambert + Torrance–Sparrow that models the highlight.

Masks and robust solvers discard the highlight as an outlier. The thesis's own
reflectance model (Eq. 2.14) says how a highlight depends on the normal, so tsfit
keeps those observations and fits the model to them; see :func:`tsfit`.
"""
from __future__ import annotations

import contextlib
import time
import warnings
from dataclasses import dataclass

import numpy as np

from ...._shared.checks import PsbenchError
from ....registry import Method
from ...base import Fit, Options, check_choice, check_int, check_number
from . import _lm, _grid as _tsgrid, _prop as _tsprop, _shared_lobe as _tsshared
from ._heldout import fall_back as _fall_back
from ._heldout import heldout as _heldout, lazy_heldout as _lazy_heldout
from ._start import (SIGMA_PIXELS, STARTS, count, lambert_pred, noise_sigma, put_back,
                     resolve_start, start_weights, take, unit)
from ...._shared.warn import ConvergenceWarning

__all__ = ["TsfitOptions", "tsfit", "METHOD"]

#: fewest weighted observations for a pixel to be fitted (4 unknowns + 1)
MIN_OBS = 5


@dataclass
class TsfitOptions(Options):
    """Options of :func:`tsfit` (besides the mask engine's, see :class:`Options`).

    Parameters
    ----------
    rho_s_mode : {"shared", "pixel"}
        The specular albedo: one value for the whole object, estimated from the data
        ("shared", default: the specular reflectance of one dielectric material
        hardly varies, and a per-pixel rho_s is nearly collinear with rho_d where the
        lobe is wide), or one per pixel ("pixel", for objects of several materials).
        Re-checked with ``benchmarks/defaults_study.py`` (every full-scale stress cell,
        798, plus DiLiGenT cat and bear with 96, 16 and 8 lights; rule fixed before
        measuring: the mean of the real and the stress mean NE must drop by more than
        0.05 deg without more stress cells over 0.3 deg worse than the better of least
        squares and trim). Criterion, real, stress, cells worse, mean solve s on the
        stress cells / real cases (shared 2-core machine, load 13-18): "shared" 4.806,
        5.587, 4.025, 58, 0.39 / 6.1; "pixel" 4.742, 5.452, 4.032, 50, 0.41 / 5.9;
        ``start="trim"`` 4.895, 5.732, 4.059, 55, 0.24 / 3.3. By that rule "pixel"
        would win (0.064 deg lower), but it is not the default: on noisy scenes that
        follow the model it is far from the Cramer-Rao bound the shared fit meets (5 %
        noise, sombrero2 45x16 4.87 deg against a bound of 2.11;
        ``tests/solve/methods/tsfit``). The rule is completed with the constraint it
        left out: a default keeps the method's accuracy on the scenes that follow its
        model, so "shared" stays (see the departures guide).
    m_mode : {"shared", "pixel", "fixed"}
        The lobe width m: one value for the whole object ("shared", default); one
        per pixel, started from the coarse estimate ("pixel"); or ``m_init`` held
        fixed ("fixed").
    m_init : float or None
        Start value of m (required for ``m_mode="fixed"``). None: the best of 8
        values log-spaced over [m_min, m_max] on a pixel sample.
    m_min, m_max : float
        Bounds on m, 0 < m_min < m_max (default 1 and 50: lobes between ~57 and ~1
        degrees wide).
    rho_s_max : float
        Upper bound on rho_s as a multiple of the pixel's brightest used observation
        (divided by the light power; the median of those bounds for a shared rho_s);
        > 0. Keeps rho_s finite where the lobe's peak is not sampled.
    lm_max_iter : int
        Maximum Levenberg–Marquardt iterations per pixel and round; >= 1.
    lm_tol : float
        A pixel has converged when a step moves its normal by at most ``lm_tol``
        radians, rho_d and rho_s by at most ``lm_tol`` times its albedo and m by
        ``lm_tol`` times m; in (0, 0.1).
    start : str
        The robust step giving the start and the weights: ``"auto"`` (the registered
        ``robust`` method when there is one, else ``"trimmed"``), ``"trimmed"``
        (per-pixel least squares without the darkest and brightest quarter of the
        usable observations), ``"ls"`` (the masked least-squares solution), or the
        name of any registered method. ``"trim"`` (a Lambertian start) was re-checked
        against "auto" with ``benchmarks/defaults_study.py`` (see ``rho_s_mode``):
        criterion 4.895 against 4.806 deg, "auto" stays.
    weights : {"start", "mask"}
        "start": the start step's inliers with the highlights put back: every usable
        observation gets weight 1 unless it is dark, i.e. the model predicts more
        than ``dark_sigmas`` noise scales of light and the observation is below
        ``dark_ratio`` times the prediction *and* more than ``dark_sigmas`` noise
        scales below it (the noise scale is estimated per image from the start's
        inliers, MAD); dark ones get weight 0. Decided first with the start's
        Lambert prediction, then (``refine``) with the fitted model. "mask":
        exactly the mask expression's validity (e.g. ``mask="Sh"``), nothing else.
    dark_ratio : float
        See ``weights``; in [0, 1]. 0 puts every observation back.
    dark_sigmas : float
        See ``weights``; >= 0.
    refine : int
        Rounds of re-deciding the dark observations with the fitted model instead
        of the Lambert start, refitting the pixels whose weights changed; >= 0.
    m_sample : int
        Object pixels (drawn with ``seed``) on which the shared lobe is estimated;
        >= 100.
    start_grid : int
        Candidate normals (a uniform hemisphere lattice) of a global start search;
        each pixel starts from the best of them and the robust start. 0 (default):
        from the robust start alone (with the repair restarts and the neighbour
        propagation, a 64-normal search was measured as no more accurate on the
        rendered scenes and DiLiGenT cat and bear, and slower).
    propagate : int
        Sweeps of neighbour propagation (pixels whose normal disagrees with their
        neighbours restart from their neighbours' mean normal and keep the refit if
        it lowers their own cost); >= 0, 0: off.
    fallback : bool
        The held-out fallback (default True; :mod:`psbench.solve.fallback`): a pixel
        keeps the fit only where it predicts the held-out observations (over the
        observations the fit or its start used) better than the start does; elsewhere
        it keeps the start's solution bit for bit (``Result.fallback``). False: the
        fit everywhere (``Result.fallback`` None). It gains on DiLiGenT and on scenes
        the model does not explain, and costs some accuracy where it does: 5 % noise
        TS renders at 96^2, sombrero2 45x16 2.20 -> 2.41 deg, semisphere_disc 45x16
        4.47 -> 4.58 deg; with 6-8 lights more (see :mod:`psbench.solve.fallback`).
    """

    rho_s_mode: str = "shared"
    m_mode: str = "shared"
    m_init: float | None = None
    m_min: float = 1.0
    m_max: float = 50.0
    rho_s_max: float = 10.0
    lm_max_iter: int = 100
    lm_tol: float = 1e-3
    start: str = "auto"
    weights: str = "start"
    dark_ratio: float = 0.5
    dark_sigmas: float = 3.0
    refine: int = 1
    m_sample: int = 2000
    start_grid: int = 0
    propagate: int = 2
    fallback: bool = True

    def __post_init__(self):
        super().__post_init__()
        check_choice(self.rho_s_mode, ("shared", "pixel"), "rho_s_mode")
        check_choice(self.m_mode, ("shared", "pixel", "fixed"), "m_mode")
        check_number(self.m_min, "m_min", lo=0, lo_open=True)
        check_number(self.m_max, "m_max", lo=0, lo_open=True)
        if not self.m_min < self.m_max:
            raise PsbenchError(f"m_min must be < m_max, got m_min={self.m_min!r}, "
                               f"m_max={self.m_max!r}")
        check_number(self.m_init, "m_init", lo=self.m_min, hi=self.m_max, allow_none=True)
        if self.m_mode == "fixed" and self.m_init is None:
            raise PsbenchError("m_mode='fixed' needs m_init, a number in [m_min, m_max]")
        check_number(self.rho_s_max, "rho_s_max", lo=0, lo_open=True)
        check_int(self.lm_max_iter, "lm_max_iter", lo=1)
        check_number(self.lm_tol, "lm_tol", lo=0, hi=0.1, lo_open=True, hi_open=True)
        if not isinstance(self.start, str) or not self.start:
            raise PsbenchError(f"start must be a method name, got {self.start!r}")
        if self.start not in STARTS:
            from .... import registry
            if self.start.lower() == "tsfit":
                raise PsbenchError("start='tsfit' is not allowed (tsfit cannot start from itself)")
            valid = [n for n in registry.names("methods") if n != "tsfit"]
            if self.start not in valid:
                raise PsbenchError(f"start={self.start!r} is not known; valid choices: "
                                   f"{', '.join(list(STARTS) + valid)}")
        check_choice(self.weights, ("start", "mask"), "weights")
        check_number(self.dark_ratio, "dark_ratio", lo=0, hi=1)
        check_number(self.dark_sigmas, "dark_sigmas", lo=0)
        check_int(self.refine, "refine", lo=0)
        check_int(self.m_sample, "m_sample", lo=100)
        check_int(self.start_grid, "start_grid", lo=0)
        check_int(self.propagate, "propagate", lo=0)
        if not isinstance(self.fallback, (bool, np.bool_)):
            raise PsbenchError(f"fallback must be True or False, got {self.fallback!r}")


def tsfit(problem, options=None) -> Fit:
    r"""Fit Lambert + Torrance–Sparrow per pixel, the highlight included.

    Model (thesis Eq. 2.14–2.15, in the form :func:`psbench.render` renders with
    ``model="ts"``): for light i with unit direction d_i and power mu_i (s_i = mu_i
    d_i), orthographic view v = (0, 0, 1) and bisector h_i = (d_i + v) / |d_i + v|,

    .. math::

        I_i = \mu_i \left[\rho_d\, (d_i \cdot n) + \rho_s\, e^{-m^2 \theta_i^2}\right]
        \ \text{if}\ d_i \cdot n > 0,\ \text{else}\ 0, \qquad
        \theta_i = \arccos(h_i \cdot n).

    tsfit minimises, per pixel, :math:`\sum_i w_i (I_i - f_i)^2` over the unit normal
    n (two angles), :math:`\rho_d \ge 0`, and, per pixel or shared by the whole
    object (``rho_s_mode``, ``m_mode``; both shared by default),
    :math:`0 \le \rho_s \le` ``rho_s_max`` times the pixel's brightest used
    observation and m in [``m_min``, ``m_max``]. Self shadows are part of the model
    (f = 0 where d_i . n <= 0); cast shadows are not, and are left out by the weights.

    Assumptions: distant lights (a layout's positions, if any, are ignored; the
    direction is the same at every pixel), orthographic view along +z, linear
    images, the Torrance–Sparrow form of Eq. 2.14 with a Gaussian lobe in the angle
    between n and h_i (no Fresnel, geometric attenuation or 1 / (n . v) factor), the
    highlight switched off in self shadow and both terms scaled by the light power,
    exactly as :func:`psbench.render` renders it; so noiseless scenes rendered that
    way are fitted exactly. Real materials follow it only approximately.

    Algorithm:

    1. **Start and weights.** A robust step (option ``start``; default the
       registered ``robust`` method, else a private rank-trimmed least squares)
       gives rho * n and per-observation weights; the highlights it dropped are put
       back (``weights``): every observation gets weight 1 unless it is clearly
       darker than the model predicts (a cast shadow), by a noise scale estimated
       per image (MAD of the residuals). The mask expression's validity
       (``problem.valid``, e.g. ``mask="Sh"``) always applies.
    2. **Shared lobe** (rho_s and/or m). On ``m_sample`` random object pixels: the
       m of a log grid that explains the sample best, per-pixel fits, then
       Gauss–Newton steps on the shared unknowns with every pixel's own unknowns
       projected out (Schur complement of the per-pixel normal equations), each
       followed by a warm-started refit and accepted only if the total cost drops.
    3. **Start of each pixel.** The robust start's normal, or (``start_grid`` > 0)
       the best of it and ``start_grid`` candidate normals (a hemisphere lattice;
       costs for all pixels at once by matrix products, rho_d in closed form);
       rho_d (and a per-pixel rho_s) in closed form.
    4. **Per-pixel fit.** Levenberg–Marquardt on every object pixel, each pixel
       fitted on its own by a compiled kernel (in parallel over pixels; numba's
       threads): 3 to 5 unknowns per pixel, normal equations solved by Cholesky,
       Marquardt damping, an active set for unknowns at their bounds. The normal
       moves on the sphere, n <- normalize(n + a t1 + b t2) with (t1, t2) a tangent
       basis at the current n, so it stays unit and has no pole singularity. A
       pixel stops when a step is below ``lm_tol`` (that step is taken without
       evaluating it unless it moves the normal across a self-shadow terminator,
       where the model jumps) or after ``lm_max_iter`` iterations; pixels are
       fitted in memory-bounded groups. Pixels whose residual ends above twice the
       median restart from the best of 256 hemisphere normals and keep the better
       fit.
    5. **Refine** (``refine`` rounds): the dark observations are re-decided with
       the fitted model instead of the Lambert start, and the pixels whose weights
       changed are refitted from their solution.
    6. **Neighbour propagation** (``propagate`` sweeps): a pixel whose normal
       differs from the mean normal of its 8 neighbours by more than 3 times the
       median of that difference restarts from that mean and keeps the refit if
       it lowers its own cost (nothing is smoothed; see
       :mod:`psbench.solve.methods.tsfit._prop`).

    Accuracy: on noisy scenes rendered with this model the fit is close to the
    Cramér–Rao bound of a per-pixel estimator (measured within 3-20 % on the
    disc-only hemisphere and sombrero2, 16 lights, 5 % noise; the gap is at grazing
    normals); no unbiased per-pixel method can beat that bound, only a spatial
    prior could. On real photographs and Phong-rendered scenes the model is an
    approximation (see ``benchmarks/tsfit.py``). The matrix products of the grid
    searches run with one BLAS thread (they are small); the per-pixel kernels use
    numba's threads (results do not depend on their number).

    Pixels with fewer than 5 observations of positive weight, or a zero start
    albedo, keep the start (rho_s = 0, flagged in ``info["kept_start"]``).

    Parameters
    ----------
    problem : psbench.solve.base.Problem
    options : TsfitOptions, optional

    Returns
    -------
    Fit
        ``b = rho_d * n`` (H, W, 3) float32 (0 outside the object); ``weights``
        (k, H, W) float32 the weights of the final fit (``valid`` = weights > 0);
        ``iterations`` (H, W) int32 LM iterations per pixel (all rounds);
        ``converged`` (H, W) bool; ``info``: ``rho_s`` and ``m`` (a float when shared
        or fixed, else (H, W) float32), ``rms`` (H, W) weighted RMS residual of the
        fit, ``kept_start`` (H, W) bool, ``start`` (the start step used), ``sigma``
        (k,) the noise scales of the final weights (None with ``weights="mask"``),
        ``timings`` and ``cpu_timings`` (wall and CPU seconds per stage: start,
        lobe, fit, propagate, total; CPU time is that of the whole process).
        Non-converged pixels keep their best estimate (LM only accepts steps that lower the cost) and raise a
        RuntimeWarning; no NaN is ever returned.
    """
    opt = options if options is not None else TsfitOptions()
    if not isinstance(opt, TsfitOptions):
        raise PsbenchError(f"options must be TsfitOptions, got {type(opt).__name__}")
    images = problem.images
    k, H, W = images.shape
    if k < MIN_OBS:
        raise PsbenchError(f"images: tsfit needs at least {MIN_OBS} images (4 unknowns per "
                           f"pixel), got {k}")
    start_name = resolve_start(opt.start)
    with _single_thread_blas():
        return _tsfit(problem, opt, start_name)


def tsfit_lazy_heldout(problem, options):
    """:func:`tsfit` without the fallback, for a caller that needs the fit's held-out
    errors at some pixels only (``robust``: where it chooses the fit). ``fields["ve"]``
    is None and ``heldout`` a function of pixel indices ``sel`` (into the object
    pixels) returning the held-out errors (k, len(sel)) float32, the observations used
    (k, len(sel)) bool and the validation error (len(sel),) float32: bit for bit
    those :func:`tsfit` computes at those pixels."""
    if options.fallback:
        raise PsbenchError("tsfit_lazy_heldout: options.fallback must be False")
    with _single_thread_blas():
        return _tsfit(problem, options, resolve_start(options.start), lazy=True)


#: run a fit with one BLAS thread (see :func:`_single_thread_blas`); benchmarks
#: switch it off to measure the difference
PIN_BLAS = True


def _single_thread_blas():
    """One BLAS thread for the duration of a fit: tsfit's matrix products are small
    ((6, k) x (k, 4096)); a multi-threaded BLAS spends more time synchronising its
    threads than computing (measured: 4x the CPU time at 512^2 x 16 on 2 cores)."""
    if not PIN_BLAS:
        return contextlib.nullcontext()
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - a declared dependency
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _tsfit(problem, opt, start_name, lazy=False):
    images = problem.images
    k, H, W = images.shape
    clock = _Clock()

    obj = np.asarray(problem.object_mask, dtype=bool).reshape(-1)
    idx = np.flatnonzero(obj)
    full = idx.size == H * W  # the object is the whole image: no gathering
    I = np.ascontiguousarray(images.reshape(k, -1) if full else take(images.reshape(k, -1), idx),
                             dtype=np.float32)  # (k, P)
    valid = np.asarray(problem.valid, dtype=bool).reshape(k, -1)
    valid = valid if full else take(valid, idx)
    lay = problem.lights
    L = _lm.Lights(lay.directions, lay.power)
    S = L.d.astype(np.float64) * L.mu[:, None]

    b0, w_start, h_start = start_weights(problem, start_name, idx, I, valid,
                                         want_heldout=True)
    if not opt.fallback:
        h_start = None
    elif h_start is None:   # a Lambertian start: its weighted LS fit
        from ...validation import lambert_heldout
        h_start = (lambert_heldout(I, S, w_start), w_start, None)
    n0, rd0 = unit(b0)
    sigma = None
    if opt.weights == "start":
        step = max(1, idx.size // SIGMA_PIXELS)
        sub = slice(0, None, step)
        sigma = noise_sigma(I[:, sub], lambert_pred(b0[:, sub], S), w_start[:, sub],
                            lambert=True)
        del w_start   # (the fallback keeps its own reference in h_start)
        w = put_back(I, valid, (L, n0, rd0, None, None), sigma, opt.dark_ratio,
                     opt.dark_sigmas)
    else:
        del w_start
        w = valid.copy()  # weights are 0 or 1: kept as bool (a quarter of the memory)
    clock.stage("start")

    inv_mu = (1.0 / np.where(L.mu > 0, L.mu, 1))[:, None]
    top = np.empty(idx.size, dtype=np.float32)
    for lo in range(0, idx.size, 1 << 16):
        s = slice(lo, lo + (1 << 16))
        top[s] = (I[:, s] * inv_mu * w[:, s]).max(axis=0)
    rs_max = (opt.rho_s_max * top).astype(np.float32)
    fitted = (count(w) >= MIN_OBS) & (rd0 > 0)
    f = np.flatnonzero(fitted)

    rs_shared, m_shared = _tsshared.estimate(L, I, w, n0, rs_max, opt, problem.seed, f)
    clock.stage("lobe")

    P = idx.size
    n, rd = n0.copy(), rd0.copy()
    rs = np.full(P, rs_shared or 0.0, dtype=np.float32)
    m = np.full(P, m_shared, dtype=np.float32)
    cols = (() if rs_shared is not None else ("rs",)) + (("m",) if opt.m_mode == "pixel" else ())
    iters = np.zeros(P, dtype=np.int32)
    conv = np.ones(P, dtype=bool)
    cost = np.zeros(P)
    _fit_subset(L, I, w, n, rd, rs, m, rs_max, f, cols, opt, iters, conv, cost,
                start=(m_shared, rs_shared is not None))
    _repair(L, I, w, n, rd, rs, m, rs_max, f, cols, opt, iters, conv, cost, m_shared,
            rs_shared)
    for _ in range(opt.refine if opt.weights == "start" else 0):
        step = max(1, P // SIGMA_PIXELS)
        sub = slice(0, None, step)
        pred = _lm.predict(L, n[:, sub], rd[sub], rs[sub], m[sub])
        sigma = noise_sigma(I[:, sub], pred, w[:, sub])
        # (the prediction of every pixel when the sample is all of them)
        w_new = put_back(I, valid, (L, n, rd, rs, m), sigma, opt.dark_ratio,
                         opt.dark_sigmas, pred=pred if step == 1 else None)
        del pred
        changed = fitted & (w_new != w).any(axis=0)
        w = w_new
        ok = changed & (count(w) >= MIN_OBS)
        if not ok.any():
            break
        _fit_subset(L, I, w, n, rd, rs, m, rs_max, np.flatnonzero(ok), cols, opt, iters,
                    conv, cost)
    clock.stage("fit")

    n_prop = 0
    if opt.propagate and f.size:
        grid = _tsprop.Grid(idx, (H, W), fitted)
        n_prop = _tsprop.propagate(L, I, w, n, rd, rs, m, rs_max, cost, grid, cols, opt, iters,
                                   conv, rs_shared is not None, sweeps=opt.propagate)
    clock.stage("propagate")

    # never return NaN: a pixel that went non-finite keeps its start
    bad = ~(np.isfinite(n).all(0) & np.isfinite(rd) & np.isfinite(rs) & np.isfinite(m))
    keep = ~fitted | bad
    if keep.any():
        n[:, keep], rd[keep], rs[keep] = n0[:, keep], rd0[keep], 0.0
        m[keep] = m_shared
        conv[bad] = False
    if lazy:    # (no fallback: nothing below needs them)
        heldout = _lazy_heldout(L, I, w, n, rd, rs, m)
        e_fit = vals = None
    else:
        e_fit, vals = _heldout(L, I, w, n, rd, rs, m)
    fell = None
    if opt.fallback:
        if sigma is None:   # weights="mask": the noise scale of the final fit
            sub = slice(0, None, max(1, P // SIGMA_PIXELS))
            sigma = noise_sigma(I[:, sub], _lm.predict(L, n[:, sub], rd[sub], rs[sub],
                                                       m[sub]), w[:, sub])
        fell, margin = _fall_back(I, w, e_fit, vals, h_start, sigma, keep, problem.scale)
        del h_start
        n[:, fell], rd[fell], rs[fell], m[fell] = n0[:, fell], rd0[fell], 0.0, m_shared
        conv[fell & ~bad] = True
    nconv = int((~conv).sum())
    if nconv:
        warnings.warn(f"tsfit: {nconv} of {P} object pixels did not converge within "
                      f"lm_max_iter={opt.lm_max_iter} and keep their best estimate (a "
                      "larger options.lm_max_iter lets them go on)",
                      ConvergenceWarning, stacklevel=2)

    def plane(v, fill=0, dtype=np.float32):
        out = np.full(H * W, fill, dtype=dtype)
        out[idx] = v
        return out.reshape(H, W)

    b = np.zeros((H * W, 3), dtype=np.float32)
    b[idx] = (n * rd).T
    if fell is not None:   # the start's solution, bit for bit
        b[idx[fell]] = b0[:, fell].T
    from ...validation import summarise
    ve = None if lazy else summarise(vals, idx, (H, W))
    clock.stage("validate")
    del valid
    if not lazy:
        del I   # the gathered copy: not needed for the output
    if full:
        wfull = w.astype(np.float32)
    else:
        wfull = np.array(problem.valid, dtype=np.float32).reshape(k, -1)
        for i in range(k):  # row by row: faster than a 2-d fancy assignment
            wfull[i, idx] = w[i]
    wsum = np.maximum(count(w), 1).astype(np.float64)
    info = dict(rho_s=rs_shared if rs_shared is not None else plane(rs),
                m=m_shared if opt.m_mode != "pixel" else plane(m, m_shared),
                rms=plane(np.sqrt(cost / wsum)), start=start_name,
                kept_start=plane(keep, False, bool), sigma=sigma, propagated=n_prop,
                timings=clock.wall(), cpu_timings=clock.cpu())
    if fell is not None:
        info.update(fallback_fraction=float(fell.mean()) if P else 0.0,
                    fallback_margin=plane(margin, np.nan))
    return Fit(b=b.reshape(H, W, 3), valid=(wfull > 0).reshape(k, H, W),
               weights=wfull.reshape(k, H, W), iterations=plane(iters, 0, np.int32),
               converged=plane(conv, True, bool), info=info,
               fields={"ve": ve, "fallback": None if fell is None else plane(fell, False, bool)},
               heldout=heldout if lazy else (e_fit, w, vals))


class _Clock:
    """Wall and CPU seconds per stage (``stage(name)`` closes the running one)."""

    def __init__(self):
        self.t = self.t0 = (time.perf_counter(), time.process_time())
        self.stages = {}

    def stage(self, name):
        now = (time.perf_counter(), time.process_time())
        self.stages[name] = (now[0] - self.t[0], now[1] - self.t[1])
        self.t = now

    def wall(self):
        return dict({k: v[0] for k, v in self.stages.items()},
                    total=time.perf_counter() - self.t0[0])

    def cpu(self):
        return dict({k: v[1] for k, v in self.stages.items()},
                    total=time.process_time() - self.t0[1])


#: pixels whose RMS residual exceeds this multiple of the median are searched again,
#: from the best of this many hemisphere normals
REPAIR, REPAIR_GRID = 2.0, 256


def _repair(L, I, w, n, rd, rs, m, rs_max, f, cols, opt, iters, conv, cost, m_shared,
            rs_shared):
    """Restart the worst-fitting pixels from the best normal of a hemisphere grid and
    keep the lower cost (a start in the wrong basin ends with a high residual)."""
    if f.size == 0:
        return
    rms = np.sqrt(cost[f] / np.maximum(count(take(w, f)), 1))
    sel = f[rms > REPAIR * np.median(rms)]
    if sel.size == 0:
        return
    Is, ws = take(I, sel), take(w, sel)
    rs_fixed = None if rs_shared is None else rs[sel]
    ms = np.full(sel.size, m_shared, dtype=np.float32)
    ns = _tsgrid.grid_start(L, Is, ws, n[:, sel], m_shared, REPAIR_GRID, rs=rs_fixed)[0]
    rds, rss = _lm.init_rho(L, Is, ws, ns, ms, rs_max[sel], rs=rs_fixed)
    it, cv, c = _lm.fit(L, Is, ws, ns, rds, rss, ms, rs_max[sel], cols=cols, m_lo=opt.m_min,
                        m_hi=opt.m_max, max_iter=opt.lm_max_iter, tol=opt.lm_tol)
    iters[sel] += it
    b = c < cost[sel]
    pick = sel[b]
    n[:, pick], rd[pick], rs[pick], m[pick] = ns[:, b], rds[b], rss[b], ms[b]
    conv[pick], cost[pick] = cv[b], c[b]


#: observations (k x pixels) gathered at once for a fit: bounds the memory of the
#: fit's per-pixel state and of the gathered copies
FIT_ELEMS = 1 << 22


def _fit_subset(L, I, w, n, rd, rs, m, rs_max, sel, cols, opt, iters, conv, cost, *,
                start=None):
    """LM on the pixels ``sel`` (in place on the per-pixel arrays), in memory-bounded
    groups. ``start=(m_value, rs_shared)``: first set the start of each pixel (the
    best of ``opt.start_grid`` hemisphere normals and its own, rho in closed form)."""
    group = max(4096, FIT_ELEMS // I.shape[0])
    for lo in range(0, sel.size, group):
        g = sel[lo:lo + group]
        cut = g.size == rd.size or (g[-1] - g[0] + 1 == g.size)  # a contiguous range
        pick = (lambda a: a[..., g[0]:g[-1] + 1]) if cut else (lambda a: take(a, g))
        Ig, wg, rsm = pick(I), pick(w), pick(rs_max)
        ns, rds, rss, ms = (pick(a).copy() for a in (n, rd, rs, m))
        if start is not None:
            m_value, rs_is_shared = start
            rsf = rss if rs_is_shared else None
            if opt.start_grid:
                ns = _tsgrid.grid_start(L, Ig, wg, ns, m_value, opt.start_grid, rs=rsf)[0]
            rds, rss = _lm.init_rho(L, Ig, wg, ns, ms, rsm, rs=rsf)
        it, cv, c = _lm.fit(L, Ig, wg, ns, rds, rss, ms, rsm, cols=cols, m_lo=opt.m_min,
                            m_hi=opt.m_max, max_iter=opt.lm_max_iter, tol=opt.lm_tol)
        n[:, g], rd[g], rs[g], m[g] = ns, rds, rss, ms
        iters[g] += it
        conv[g] = cv
        cost[g] = c


METHOD = Method(name="tsfit", func=tsfit, options=TsfitOptions,
                help="per-pixel Lambert + Torrance-Sparrow fit that models the highlight "
                     "(starts from a robust solution)")
