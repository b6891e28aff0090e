"""Unified photometric stereo (Chapter 3): ``solve`` and its ``Result``.

Flow (Fig. 3.1), as composable stages:

1. **subsets** (step 3): subset masks xNL / RA (from :mod:`psbench.solve.subset`)
   give per-observation validity; CJ gives the fused solution directly (k = 4).
2. **image masks** (step 4): Th (Eq. 3.2), NL (Eqs. 3.3-3.6, k = 4).
3. **PS <-> normal masks** (steps 5-6): solve, compute SS / Re / CS / Hi / Sh from the
   normals, AND them with the image and subset masks, solve again, until the valid
   masks stop changing or ``max_iter`` rounds. After the first round only pixels whose
   mask changed are solved again (the local masks depend on the pixel's own normal
   only; with Sh the masks are re-evaluated on every pixel each round).
4. **fuse** (step 7) / weighting: the weighted-mask step (Eq. 3.19) or FWLSE.

Before every PS solve Eq. 3.1's rule is applied: where fewer than three observations
are valid the masked ones with the least residual of the *unmasked* least-squares
solution are added back until three are used
(:func:`psbench.solve.kernel.complete_three`). Every per-pixel solve goes through
:func:`psbench.solve.kernel.wls`. Caveat: with k = 4 lights the residual of the
unmasked solution lies in the one-dimensional null space of S^T, r = a (a . I), so on
a symmetric ring (|a_i| all equal) the four residuals of a pixel are equal in
magnitude and Eq. 3.1 cannot rank them; ties go to the lowest light index (stable
sort). This is why Th with 4 lights (which leaves < 3 observations at most pixels of
the Torrance-Sparrow test scenes) can end above None.

Mask names are joined by '-' (whitespace also accepted); a combination is the logical
AND of validity. See :mod:`psbench.solve.masks` for the per-mask decisions (Th offset
and scopes, NL rule, Re/SS sign corrections) and :mod:`psbench.solve.thresholds` for
Table 5.2 and its interpolation.

Degenerate input: all-zero images give normals (0, 0, 1), albedo 0 and a
RuntimeWarning; images with zero dynamic range (each image constant) make the
range-based masks (Th, Hi, CS, NL) mask nothing (strict bounds) and warn -- such a
stack is a plane under distant lights, which least squares solves exactly.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from .._checks import PsbenchError, as_images, as_mask, as_normals, choice
from . import kernel, masks as M
from .thresholds import resolve_thresholds, t_re_array
from .weighted import DEFAULTS as W_DEFAULTS, fwlse as _fwlse, weighted_masks

__all__ = ["solve", "Result", "MASKS", "METHODS", "parse_mask", "OPTIONS"]

#: valid mask tokens
MASKS = ("None", "Th", "NL", "xNL", "SS", "Re", "CS", "Hi", "Sh", "CJ", "RA")
#: valid methods
METHODS = ("ps", "fwlse", "wps")
IMAGE_MASKS = ("Th", "NL")
NORMAL_MASKS = ("SS", "Re", "CS", "Hi", "Sh")
SUBSET_MASKS = ("xNL", "RA", "CJ")

#: extra keyword options of :func:`solve` and their defaults
OPTIONS = dict(W_DEFAULTS, th_offset=False, sh_bias=None, integrate_method="poisson",
               n_subsets=None, iter_tol=1e-3)


class _Lazy:
    """A :class:`Result` field that may be given as a zero-argument function: it is
    computed on first access and then kept (the unmasked residual map costs as much as
    the whole plain least-squares solve, and many callers never read it)."""

    def __set_name__(self, owner, name):
        self.slot = "_lazy_" + name

    def __get__(self, obj, objtype=None):
        if obj is None:
            raise AttributeError(self.slot)  # class access: the field has no default
        value = obj.__dict__[self.slot]
        if callable(value):
            value = value()
            obj.__dict__[self.slot] = value
        return value

    def __set__(self, obj, value):
        obj.__dict__[self.slot] = value


@dataclass(eq=False)
class Result:
    """Output of :func:`solve`.

    Attributes
    ----------
    normals : (H, W, 3) float32
        Unit normals; (0, 0, 1) where the albedo is 0 and outside ``object_mask``.
    albedo : (H, W) float32
        rho (times light power); 0 outside ``object_mask``.
    valid : (k, H, W) bool
        Binary mask actually used (True = observation used), after Eq. 3.1's
        completion; all True outside ``object_mask``.
    weights : (k, H, W) float32 or None
        Final WLS weights (weighted masks / FWLSE), normalised so that 1 = sigma_min;
        None for binary solves.
    residual : (H, W) float32
        L2 norm of i - rho s.n over the **used** observations (``valid``) of the
        final solution; 0 outside ``object_mask``.
    height : (H, W) float32 or None
        Poisson-integrated heights when ``want_height=True``.
    timings : dict
        Stage -> seconds, including "total".
    lights : Layout
    mask : str
        Canonical mask name ("Th-Hi-Re-Sh").
    method : str
    iterations : int
        PS <-> normal-mask rounds (0 without normal masks) or FWLSE iterations.
    thresholds : dict
        Resolved threshold values actually used.
    info : dict
        Extras: ``th_scope``, ``converged`` (True: no mask changed; "cycle": the
        masks returned to an earlier state; "tol": a round changed at most
        ``iter_tol`` of the object pixels; False: ``max_iter`` reached), ``changed``
        (pixels whose mask changed per round),
        ``ne`` (mean normal error per round when ``truth_normals`` was given), warnings.
    """

    normals: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    weights: np.ndarray | None
    residual: np.ndarray = _Lazy()
    height: np.ndarray | None
    timings: dict
    lights: object
    mask: str
    method: str
    iterations: int = 0
    thresholds: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    @property
    def b(self) -> np.ndarray:
        """rho * n, (H, W, 3) float32."""
        return self.normals * self.albedo[..., None]

    def __repr__(self) -> str:
        H, W = self.albedo.shape
        return (f"Result(mask={self.mask!r}, method={self.method!r}, k={self.valid.shape[0]}, "
                f"size={H}x{W}, iterations={self.iterations}, "
                f"total={self.timings.get('total', float('nan')):.3f}s)")


_CANON = {m.lower(): m for m in MASKS}


def parse_mask(mask) -> tuple[str, ...]:
    """Split a mask name into canonical tokens ('th-hi' -> ('Th', 'Hi')); () for None."""
    if mask is None:
        return ()
    if isinstance(mask, (list, tuple)):
        parts = [str(p) for p in mask]
    elif isinstance(mask, str):
        parts = mask.replace("-", " ").replace("+", " ").split()
    else:
        raise PsbenchError(f"mask must be a string like 'Th-Hi-Re-Sh', got {type(mask).__name__}")
    out = []
    for p in parts:
        c = _CANON.get(p.strip().lower())
        if c is None:
            raise PsbenchError(
                f"mask={mask!r}: unknown mask {p!r}; valid masks: {', '.join(MASKS)} "
                "(combine with '-', e.g. 'Th-Hi-Re-Sh')")
        if c != "None" and c not in out:
            out.append(c)
    if "CJ" in out and len(out) > 1:
        raise PsbenchError(f"mask={mask!r}: CJ fuses its own triplet solutions and cannot be "
                           "combined with other masks; use mask='CJ'")
    return tuple(out)


def _validate_lights(lights, k):
    from ..lights import Layout, layout
    try:
        lay = lights if isinstance(lights, Layout) else layout(lights)
    except PsbenchError:
        raise
    except Exception as exc:  # e.g. ragged lists
        raise PsbenchError(f"lights must be a Layout, a (k, 3) array or ring notation like "
                           f"'45x8'; got {lights!r:.80} ({exc})") from None
    if lay.k != k:
        raise PsbenchError(f"lights has {lay.k} lights ({lay.name}) but images holds {k} images; "
                           "they must match one to one")
    return lay


def _check_opts(opts):
    bad = [o for o in opts if o not in OPTIONS]
    if bad:
        raise PsbenchError(f"solve() got unknown option(s) {', '.join(map(repr, bad))}; valid "
                           f"options: {', '.join(OPTIONS)}")
    o = dict(OPTIONS)
    o.update(opts)
    for name in ("dilate_radius", "kernel_size"):
        v = o[name]
        if not isinstance(v, (int, np.integer)) or v < 0:
            raise PsbenchError(f"{name} must be an integer >= 0, got {v!r}")
    if o["kernel_size"] < 1 or o["kernel_size"] % 2 == 0:
        raise PsbenchError(f"kernel_size must be odd and >= 1, got {o['kernel_size']!r}")
    if not np.isscalar(o["smooth_sigma"]) or not o["smooth_sigma"] >= 0:
        raise PsbenchError(f"smooth_sigma must be a number >= 0, got {o['smooth_sigma']!r}")
    if o["sigma_min"] is not None and not (np.isscalar(o["sigma_min"]) and o["sigma_min"] > 0):
        raise PsbenchError(f"sigma_min must be a number > 0 (or None), got {o['sigma_min']!r}")
    if not (np.isscalar(o["fwlse_tol"]) and o["fwlse_tol"] > 0):
        raise PsbenchError(f"fwlse_tol must be a number > 0, got {o['fwlse_tol']!r}")
    if not (np.isscalar(o["iter_tol"]) and 0 <= o["iter_tol"] < 1):
        raise PsbenchError(f"iter_tol must be a number in [0, 1), got {o['iter_tol']!r}")
    o["integrate_method"] = choice(o["integrate_method"], ("poisson", "fc"), "integrate_method")
    return o


class _Timer:
    def __init__(self):
        self.t = {}
        self._t0 = time.perf_counter()
        self._last = self._t0

    def lap(self, name):
        now = time.perf_counter()
        self.t[name] = self.t.get(name, 0.0) + (now - self._last)
        self._last = now

    def done(self):
        self.t["total"] = time.perf_counter() - self._t0
        return self.t


def _ne(normals, truth, m):
    d = np.clip(np.einsum("hwc,hwc->hw", normals, truth), -1.0, 1.0)
    return float(np.degrees(np.arccos(d[m])).mean()) if m.any() else 0.0


def solve(images, lights, *, mask="None", method="ps", weighted=False, object_mask=None,
          thresholds=None, max_iter=10, seed=0, weight=None, binary=False, want_height=False,
          truth_normals=None, th_scope="image", **opts) -> Result:
    """Unified photometric stereo with masks (Chapter 3).

    Parameters
    ----------
    images : (k, H, W) array_like
        k >= 3 linear images; unsigned integers are converted to [0, 1]; NaN refused.
    lights : Layout, (k, 3) array_like or str
        Light layout (``"45x8"``); its count must match the images.
    mask : str
        Mask tokens joined by '-': None, Th, NL, xNL, SS, Re, CS, Hi, Sh, CJ, RA
        (NL and CJ need k = 4).
    method : {"ps", "fwlse", "wps"}
        "ps": masked least squares; "fwlse": feasible WLS (Section 3.4.1) started
        from the masked solution; "wps": delegated to :func:`psbench.solve.wps.wps`.
    weighted : bool
        Weighted masks (Section 3.4.2, Eq. 3.19) after the binary solve.
    object_mask : (H, W) bool, optional
        Pixels of the object (ranges of th_scope "object"/"robust"/"pixel", Sh
        integration, outputs). Default: all pixels.
    thresholds : dict, optional
        Overrides of Table 5.2 (see :func:`psbench.solve.thresholds.resolve_thresholds`).
    max_iter : int
        Maximum PS <-> normal-mask rounds (and FWLSE iterations); >= 0.
    seed : int
        RANSAC seed.
    weight, binary
        Passed to "wps" only.
    want_height : bool
        Integrate the final normals (Poisson) into ``Result.height``.
    truth_normals : (H, W, 3), optional
        Only for diagnostics: records the mean normal error per round in ``info["ne"]``.
    th_scope : {"image", "object", "robust", "pixel"}
        How the dynamic ranges of Th / Hi / CS are measured (see
        :mod:`psbench.solve.masks`). "image" is the thesis's rule.
    **opts
        ``dilate_radius`` (7), ``smooth_sigma`` (3), ``kernel_size`` (15),
        ``sigma_min`` (None = 1 % of the mean dynamic range), ``fwlse_tol`` (1e-3),
        ``th_offset`` (False: literal Eq. 3.2; True: Th bounds offset by i_min, see
        :mod:`psbench.solve.masks`), ``sh_bias`` (shadow-map bias,
        None = shadowmap default), ``integrate_method`` ("poisson"), ``n_subsets`` (RA),
        ``iter_tol`` (1e-3: also stop after a round that changed the mask of at most
        this fraction of the object pixels; 0: iterate until no mask changes, a
        cycle, or ``max_iter``). With Sh the masks of a few hundred shadow-boundary
        pixels keep drifting on large images (the integrated heights shift
        slightly each round; at 2048^2: 70133, 3087, 668, 372, 328, ... changed
        pixels per round, NE changing by < 0.001 deg per round), so exact
        convergence would run every remaining round at full Sh cost.

    Returns
    -------
    Result
    """
    tm = _Timer()
    images = as_images(images, "images", min_count=3)
    k, H, W = images.shape
    lay = _validate_lights(lights, k)
    tokens = parse_mask(mask)
    method = choice(method, METHODS, "method")
    th_scope = choice(th_scope, M.SCOPES, "th_scope")
    if not isinstance(max_iter, (int, np.integer)) or isinstance(max_iter, bool) or max_iter < 0:
        raise PsbenchError(f"max_iter must be an integer >= 0, got {max_iter!r}")
    for t in ("NL", "CJ"):
        if t in tokens and k != 4:
            raise PsbenchError(f"mask={mask!r}: {t} needs exactly 4 images, got {k}; use "
                               f"{'xNL' if t == 'NL' else 'RA or xNL'} for other counts")
    if ("Sh" in tokens or want_height) and min(H, W) < 2:
        raise PsbenchError(f"images of {H}x{W} pixels: the Sh mask and want_height integrate "
                           "heights and need at least 2x2 pixels")
    if "xNL" in tokens and k < 4:
        raise PsbenchError(f"mask={mask!r}: xNL needs at least 4 images, got {k}")
    omask = as_mask(object_mask, (H, W), "object_mask")
    if not omask.any():
        raise PsbenchError("object_mask selects no pixel")
    full = bool(omask.all())
    if truth_normals is not None:
        truth_normals = as_normals(truth_normals, "truth_normals", (H, W))
    o = _check_opts(opts)
    thr = resolve_thresholds(k, lay, thresholds)
    name = "-".join(tokens) if tokens else "None"

    if method == "wps":
        from .wps import wps  # owned by the wps module; imported lazily
        return wps(images, lay, mask=mask, weighted=weighted, object_mask=object_mask,
                   thresholds=thresholds, max_iter=max_iter, seed=seed, weight=weight,
                   binary=binary, want_height=want_height, truth_normals=truth_normals,
                   th_scope=th_scope, **opts)
    tm.lap("validate")

    info = {"th_scope": th_scope, "warnings": []}
    S = lay.S.astype(np.float64)
    S32 = S.astype(np.float32)
    dirs = lay.directions
    need_ranges = any(t in tokens for t in ("Th", "NL", "Hi", "CS")) or weighted or method == "fwlse"
    rg = None
    if need_ranges:
        rg = M.ranges(images, scope=th_scope, object_mask=None if full else omask,
                      offset=bool(o["th_offset"]))
        if float(np.max(rg["rng_up"])) <= 0.0:
            msg = ("images have zero dynamic range (every image constant); range-based masks "
                   "mask nothing")
            if not images.any():
                msg = "all images are zero: normals (0, 0, 1), albedo 0"
            warnings.warn(msg, RuntimeWarning, stacklevel=2)
            info["warnings"].append(msg)
        tm.lap("ranges")
    scale = rg["scale"] if rg is not None else 1.0
    sigma_min = o["sigma_min"] if o["sigma_min"] is not None else 0.01 * scale

    # ---- fast path: plain least squares ------------------------------------------
    if not tokens and method == "ps" and not weighted:
        b = kernel.ls(images, S)
        tm.lap("ps")
        valid = np.ones((k, H, W), dtype=bool)
        info["_plain_ls"] = True
        if truth_normals is not None:
            info["ne"] = [_ne(kernel.split(b)[0], truth_normals, omask)]
        return _finish(images, S32, b, valid, None, omask, full, lay, name, method, 0, thr,
                       info, tm, want_height, o, truth_normals)

    # ---- subsets (step 3) and image masks (step 4) -----------------------------------
    valid_img = None
    b_fused = None
    if "CJ" in tokens:
        from .subset import cj
        b_fused = np.asarray(cj(images, S, t_cj=thr["t_CJ"]), dtype=np.float32)
        tm.lap("subsets")
    if "xNL" in tokens:
        from .subset import xnl
        t_re_x = t_re_array(thr, k)
        t_re_x = float(t_re_x.min())  # xnl takes one angle: the smallest (multi-ring)
        valid_img = _and(valid_img, np.asarray(xnl(images, S, t_nl=thr["t_NL"], t_re=t_re_x), dtype=bool))
        tm.lap("subsets")
    if "RA" in tokens:
        from .subset import ransac
        valid_img = _and(valid_img, np.asarray(
            ransac(images, S, threshold=thr["t_RA"], n_subsets=o["n_subsets"], seed=seed), dtype=bool))
        tm.lap("subsets")
    if "Th" in tokens:
        vth = M.th(images, rg["lo"], rg["rng"], thr["k_low"], thr["k_up"],
                   lo_up=rg["lo_up"], rng_up=rg["rng_up"])
        if rg["dead"].any():
            vth |= rg["dead"]
        valid_img = _and(valid_img, vth)
        tm.lap("image_masks")
    if "NL" in tokens:
        prefer = None
        if "Re" in tokens:
            b0 = kernel.ls(images, S)
            n0, _ = kernel.split(b0)
            prefer = ~M.re(n0, dirs, t_re_array(thr, k))
        valid_img = _and(valid_img, M.nl(images, S, thr["t_NL"], scale=scale,
                                         shadow_level=rg["lo"] + np.float32(thr["k_low"]) * rg["rng"],
                                         prefer=prefer))
        tm.lap("image_masks")
    if valid_img is None:
        valid_img = np.ones((k, H, W), dtype=bool)

    # ---- PS <-> normal masks (steps 5-6) -----------------------------------------------
    normal_tokens = [t for t in tokens if t in NORMAL_MASKS]
    iterations = 0
    changed_hist = []
    ne_hist = []
    if b_fused is not None:
        b = b_fused
        valid = _cj_valid(images, S32, b, scale)
        tm.lap("fuse")
    else:
        completer = _Completer(images, S)
        valid = completer(valid_img.reshape(k, -1).copy()).reshape(k, H, W)
        b = kernel.wls(images, S, valid) if not valid.all() else kernel.ls(images, S)
        tm.lap("ps")
        if truth_normals is not None:
            ne_hist.append(_ne(kernel.split(b)[0], truth_normals, omask))
        if normal_tokens and max_iter > 0:
            b, valid, iterations, converged, changed_hist = _iterate(
                images, S, S32, dirs, b, valid, valid_img, normal_tokens, thr, rg, omask,
                full, max_iter, o, tm, truth_normals, ne_hist, completer)
            info["converged"] = converged

    # ---- weighting (step 7) ------------------------------------------------------------
    weights = None
    if method == "fwlse":
        b, weights, it_f, conv = _fwlse(images, S, b, None if valid.all() else valid,
                                        sigma_min=sigma_min, tol=o["fwlse_tol"],
                                        max_iter=max(1, max_iter), scale=scale)
        info["fwlse_iterations"] = it_f
        info["converged"] = conv
        iterations = it_f if not normal_tokens else iterations
        tm.lap("fwlse")
    if weighted:
        weights = weighted_masks(images, S, b, valid, sigma_min=sigma_min,
                                 dilate_radius=o["dilate_radius"], smooth_sigma=o["smooth_sigma"],
                                 kernel_size=o["kernel_size"], out=weights)
        tm.lap("weights")
        b = kernel.wls(images, S, weights)
        tm.lap("weighted_ps")
    info["changed"] = changed_hist
    if truth_normals is not None:
        ne_hist.append(_ne(kernel.split(b)[0], truth_normals, omask))
        info["ne"] = ne_hist
    return _finish(images, S32, b, valid, weights, omask, full, lay, name, method, iterations,
                   thr, info, tm, want_height, o, truth_normals)


def _and(a, b):
    if a is None:
        return b
    a &= b
    return a


def _mean_range(images):
    k = images.shape[0]
    f = images.reshape(k, -1)
    r = float((f.max(axis=1) - f.min(axis=1)).mean())
    return r if r > 0 else 1.0


class _Completer:
    """Eq. 3.1's rule with a per-pixel cache.

    Where fewer than three observations are valid, the masked ones with the least
    |residual| of the *unmasked* least-squares solution are added until three are
    used -- exactly :func:`psbench.solve.kernel.complete_three` (tests check the
    equivalence). The residual order of a pixel never changes during a solve, so it is
    computed once, only for pixels that ever need completion, and reused in every
    round.
    """

    def __init__(self, images, S):
        k = images.shape[0]
        self.k = k
        self.flat = images.reshape(k, -1)
        self.S = np.asarray(S, dtype=np.float64)
        self.P = np.linalg.pinv(self.S).astype(np.float32)
        self.S32 = self.S.astype(np.float32)
        self.have = np.zeros(self.flat.shape[1], dtype=bool)
        self.order = None

    def _ensure(self, cols):
        miss = cols[~self.have[cols]]
        if miss.size == 0:
            return
        if self.order is None:
            self.order = np.zeros((self.k, self.flat.shape[1]), dtype=np.uint8)
        sub = self.flat[:, miss]
        r = sub - self.S32 @ (self.P @ sub)
        np.abs(r, out=r)
        self.order[:, miss] = np.argsort(r, axis=0, kind="stable").astype(np.uint8)
        self.have[miss] = True

    def __call__(self, valid, cols=None):
        """Complete ``valid`` (k, n) in place where short; ``cols`` maps its columns to
        pixel indices (None: all pixels). Returns ``valid``."""
        k = self.k
        cnt = valid.sum(axis=0, dtype=np.uint8)
        short = np.flatnonzero(cnt < 3)
        if short.size == 0:
            return valid
        pix = short if cols is None else cols[short]
        self._ensure(pix)
        o = self.order[:, pix]
        v = valid[:, short]
        c = cnt[short]
        ar = np.arange(short.size)
        for j in range(k):
            need = c < 3
            if not need.any():
                break
            obs = o[j]
            add = need & ~v[obs, ar]
            v[obs[add], ar[add]] = True
            c += add
        valid[:, short] = v
        return valid


def _normal_valid(tokens, images, b, S32, dirs, thr, rg, t_re):
    """Local normal masks (SS, Re, CS, Hi) on (k, *P) images with b (*P, 3)."""
    v = None
    if "SS" in tokens:
        v = M.ss(b, S32)
    if "Re" in tokens:
        n, _ = kernel.split(b.reshape(1, -1, 3) if b.ndim == 2 else b)
        v = _and(v, M.re(n.reshape(b.shape), dirs, t_re))
    if "CS" in tokens or "Hi" in tokens:
        r = M.residual_lambert(images, b, S32)
        rng = rg["rng"]
        if rng.shape[0] == 1 and rng.ndim == 3 and images.ndim == 2:
            rng = rng.reshape(1, -1)
        dead = rg["dead"].reshape((-1,) + (1,) * (images.ndim - 1)) if rg["dead"].any() else None
        if "CS" in tokens:
            v = _and(v, M.cs(images, b, S32, rng, thr["k_CS"], resid=r) if dead is None
                     else M.cs(images, b, S32, rng, thr["k_CS"], resid=r) | dead)
        if "Hi" in tokens:
            v = _and(v, M.hi(images, b, S32, rng, thr["k_Hi"], resid=r) if dead is None
                     else M.hi(images, b, S32, rng, thr["k_Hi"], resid=r) | dead)
    return v


def _iterate(images, S, S32, dirs, b, valid, valid_img, tokens, thr, rg, omask, full,
             max_iter, o, tm, truth, ne_hist, completer):
    """PS <-> normal masks until the valid masks stop changing (or repeat a state of
    the previous round: a 2-cycle), or ``max_iter`` rounds.

    Local masks (SS, Re, CS, Hi) depend only on the pixel's own solution, so after the
    first round they are re-evaluated only where the solution changed; Sh is global
    (integration + shadow maps) and is recomputed on the whole image every round.
    """
    k, H, W = images.shape
    t_re = t_re_array(thr, k) if "Re" in tokens else None
    local = [t for t in tokens if t != "Sh"]
    use_sh = "Sh" in tokens
    flat_img = images.reshape(k, -1)
    flat_b = b.reshape(-1, 3)  # view into b
    flat_valid = valid.reshape(k, -1)
    if np.shares_memory(flat_valid, valid_img):
        flat_valid = flat_valid.copy()
    flat_vimg = valid_img.reshape(k, -1)
    pixel_rng = rg is not None and rg["rng"].shape[0] == 1 and rg["rng"].size > 1
    flat_rg = None
    if rg is not None:
        flat_rg = dict(rg)
        flat_rg["rng"] = rg["rng"].reshape(1, -1) if pixel_rng else rg["rng"].reshape(k, 1)
    lv = None  # local-mask validity of every pixel (k, N), kept up to date
    active = None  # pixels whose solution changed in the last round (None = all)
    changed_hist = []
    converged = False
    seen = {_digest(flat_valid)}  # states already visited (cycle detection)
    n_obj = int(omask.sum())
    tol_pix = float(o["iter_tol"]) * n_obj
    it = 0
    for it in range(1, max_iter + 1):
        if local:
            if active is None:
                lv = _normal_valid(local, flat_img, flat_b, S32, dirs, thr, flat_rg, t_re)
            elif active.size:
                sub_rg = flat_rg
                if pixel_rng:
                    sub_rg = dict(flat_rg, rng=flat_rg["rng"][:, active])
                lv[:, active] = _normal_valid(local, flat_img[:, active], flat_b[active], S32,
                                              dirs, thr, sub_rg, t_re)
        if use_sh:
            tm.lap("normal_masks")
            n_full, _ = kernel.split(b)
            vsh, _ = M.sh(n_full, b, S32, dirs, None if full else omask,
                          bias=o["sh_bias"], method=o["integrate_method"])
            tm.lap("sh")
            new = vsh.reshape(k, -1)
            if lv is not None:
                new &= lv
            new &= flat_vimg
            cols = None
        elif active is None:
            new = lv & flat_vimg
            cols = None
        else:
            cols = active
            new = lv[:, cols] & flat_vimg[:, cols]
        completer(new, cols)
        tm.lap("normal_masks")
        if cols is None:
            diff = (new != flat_valid).any(axis=0)
            idx = np.flatnonzero(diff)
            new = new[:, idx]
        else:
            diff = (new != flat_valid[:, cols]).any(axis=0)
            idx = cols[diff]
            new = new[:, diff]
        changed_hist.append(int(idx.size))
        if idx.size == 0:
            converged = True
            it -= 1
            break
        old = flat_valid[:, idx].copy()
        flat_valid[:, idx] = new
        key = _digest(flat_valid)
        if key in seen:
            # the masks returned to a state of an earlier round: a cycle; keep the
            # previous state and stop
            flat_valid[:, idx] = old
            converged = "cycle"
            it -= 1
            break
        seen.add(key)
        flat_b[idx] = kernel.wls(flat_img[:, idx][:, None, :], S, new[:, None, :]).reshape(-1, 3)
        active = idx
        tm.lap("ps_iter")
        if truth is not None:
            ne_hist.append(_ne(kernel.split(b)[0], truth, omask))
        if idx.size <= tol_pix:
            converged = "tol"
            break
    return b, flat_valid.reshape(k, H, W), it, converged, changed_hist


def _digest(valid):
    import hashlib
    return hashlib.blake2b(np.packbits(valid).tobytes(), digest_size=16).digest()


def _cj_valid(images, S32, b, scale):
    """Observations CJ used: where exactly three residuals vanish, the fourth was
    excluded (the smallest-albedo triplet was chosen); otherwise all four."""
    r = np.abs(M.residual_lambert(images, b, S32))
    tol = np.float32(1e-4 * scale)
    small = r <= tol
    three = small.sum(axis=0) == 3
    valid = np.ones_like(small)
    valid[:, three] = small[:, three]
    return valid


def _finish(images, S32, b, valid, weights, omask, full, lay, name, method, iterations, thr,
            info, tm, want_height, o, truth):
    normals, albedo = kernel.split(b)
    if not info["warnings"] and not albedo.any() and not images.any():
        # (checked on the albedo first: a full pass over the images only when needed)
        msg = "all images are zero: normals (0, 0, 1), albedo 0"
        warnings.warn(msg, RuntimeWarning, stacklevel=3)
        info["warnings"].append(msg)
    tm.lap("split")
    k, H, W = images.shape
    out = None if full else ~omask
    if info.pop("_plain_ls", False):
        # computed when first read (Result.residual is lazy for the unmasked solve)
        def resid():
            r = _residual_ls(images, S32)
            if out is not None:
                r[out] = 0.0
            return r
    else:
        resid = _residual(images, b, S32, None if valid.all() else valid)
        if out is not None:
            resid[out] = 0.0
        tm.lap("residual")
    if not full:
        normals[out] = (0.0, 0.0, 1.0)
        albedo[out] = 0.0
        if not valid[:, out].all():
            valid[:, out] = True
        if weights is not None:
            weights[:, out] = 0.0
    height = None
    if want_height:
        from ..integrate import integrate
        height = np.asarray(integrate(normals, None if full else omask,
                                      method=o["integrate_method"]), dtype=np.float32)
        tm.lap("height")
    return Result(normals=normals, albedo=albedo, valid=valid, weights=weights, residual=resid,
                  height=height, timings=tm.done(), lights=lay, mask=name, method=method,
                  iterations=int(iterations), thresholds=thr, info=info)


def _residual(images, b, S32, valid=None):
    """sqrt(sum_i valid_i (i - rho s_i.n)^2), (H, W) float32, chunked over pixels
    (chunks small enough to stay in cache). ``valid=None``: all observations."""
    k, H, W = images.shape
    N = H * W
    I2 = images.reshape(k, -1)
    B = b.reshape(-1, 3)
    V = None if valid is None else valid.reshape(k, -1)
    out = np.empty(N, dtype=np.float32)
    step = 16384
    for lo in range(0, N, step):
        hi = min(N, lo + step)
        r = I2[:, lo:hi] - S32 @ B[lo:hi].T
        r *= r
        if V is not None:
            r *= V[:, lo:hi]
        out[lo:hi] = r.sum(axis=0)
    np.sqrt(out, out=out)
    return out.reshape(H, W)


def _residual_ls(images, S):
    """Residual norm of the unmasked least-squares solution, exactly, from the
    coordinates of I in an orthonormal basis of null(S^T): |I - S S^+ I| = |U_perp^T I|."""
    k, H, W = images.shape
    if k == 3:
        return np.zeros((H, W), dtype=np.float32)
    U = np.linalg.svd(np.asarray(S, dtype=np.float64), full_matrices=True)[0][:, 3:]
    U = np.ascontiguousarray(U.T, dtype=np.float32)  # (k - 3, k)
    I2 = images.reshape(k, -1)
    N = I2.shape[1]
    out = np.empty(N, dtype=np.float32)
    step = 4096  # keeps the (k - 3, step) block in cache
    X = np.empty((k - 3, step), dtype=np.float32)
    for lo in range(0, N, step):
        hi = min(N, lo + step)
        Xv = X[:, :hi - lo]
        np.matmul(U, I2[:, lo:hi], out=Xv)
        Xv *= Xv
        Xv.sum(axis=0, out=out[lo:hi])
    np.sqrt(out, out=out)
    return out.reshape(H, W)
