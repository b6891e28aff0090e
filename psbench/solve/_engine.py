"""The mask engine: Fig. 3.1 as one function, used by :func:`psbench.solve` and, per
ring, by WPS (through ``Problem.engine``).

1. **subsets** (step 3): subset masks (xNL, RA) give per-observation validity; a
   fusing subset mask (CJ) gives the solution directly.
2. **image masks** (step 4): Th (Eq. 3.2), NL (Eqs. 3.3-3.6).
3. **PS <-> normal masks** (steps 5-6): solve, compute the normal masks (SS, Re, CS, Hi,
   Sh) from the normals, AND them with the image and subset masks, solve again, until
   the valid masks stop changing, return to an earlier state (a cycle), change at most
   ``iter_tol`` of the object pixels, or ``max_iter`` rounds. After the first round the
   local masks are re-evaluated, and the pixels solved again, only where something
   changed; global masks (Sh) are re-evaluated on every pixel each round.
4. **method**, then the **weighted-mask step** (Eq. 3.19) when ``weighted``.

A global normal mask may also return a correction of the images (SR: the predicted
secondary light); the engine then solves, masks, completes and weights the corrected
images ``images - correction`` (contract and stopping rule: *Corrections* in
:mod:`psbench.solve.base`). Without corrections nothing of this path runs.

Before every PS solve Eq. 3.1's rule is applied: where fewer than three observations
are valid the masked ones with the least residual of the *unmasked* least-squares
solution are added back until three are used
(:func:`psbench.solve.kernel.complete_three`). Caveat: with k = 4 lights the residual
of the unmasked solution lies in the one-dimensional null space of S^T, r = a (a . I),
so on a symmetric ring (|a_i| all equal) the four residuals of a pixel are equal in
magnitude and Eq. 3.1 cannot rank them; ties go to the lowest light index (stable
sort). This is why Th with 4 lights (which leaves < 3 observations at most pixels of
the Torrance-Sparrow test scenes) can end above None.
"""
from __future__ import annotations

import hashlib
import warnings

import numpy as np

from .._shared.checks import PsbenchError
from . import _complete_kernel as _ck
from . import kernel
from ._result import Timer, finish, mean_error
from ._specs import check_counts, mask_specs
from .base import Context, Fit, Problem
from .masks._ranges import ranges
from .thresholds import resolve_thresholds
from .weighted import weighted_masks

__all__ = ["run"]


def run(images, lights, *, tokens, thresholds, options, object_mask, seed=0, method=None,
        overrides=None, want_height=False, truth=None, timer=None, masks=None):
    """One solve on validated input: masks, method, weighted step, Result.

    Parameters
    ----------
    images : (k, H, W) float32
    lights : Layout
    tokens : tuple of str
        Canonical mask names.
    thresholds : dict
        Resolved for these images; ``overrides`` are the user's (re-resolved for the
        images of ``Problem.engine`` calls).
    options : Options
    object_mask : (H, W) bool
    method : psbench.registry.Method or None
        None: masked least squares (the "ps" method) without a Problem.
    truth : (H, W, 3) or None
        Diagnostics: mean normal error per round in ``info["ne"]``.
    masks : dict, optional
        name -> Mask (default: the registered masks, read once per solve).
    """
    timer = timer or Timer()
    need = getattr(options, "min_images", 0)   # e.g. rpca: refused before any work
    if method is not None and images.shape[0] < need:
        raise PsbenchError(f"method {method.name!r} needs at least {need} images, got "
                           f"{images.shape[0]}")
    masks = mask_specs() if masks is None else masks
    specs = [masks[t] for t in tokens]
    ctx = Context(images, lights, tuple(tokens), thresholds, options, object_mask, seed)
    info = {"th_scope": options.th_scope, "warnings": ctx.warnings}
    masked = method is None or method.masked
    if masked and (any(s.ranges for s in specs) or options.weighted or options.needs_ranges):
        _measure(ctx)
        timer.lap("ranges")
    ne = [] if truth is not None else None
    name = "-".join(tokens) if tokens else "None"
    rounds, changed = 0, []
    work = images  # the images solved: the corrected ones when a mask corrects them
    if masked:
        b, valid, rounds, conv, changed, corr = _masked_ps(ctx, specs, timer, truth, ne)
        if conv is not None:
            info["converged"] = conv
        if corr is not None:
            work = corr.pop("images")
            info.update(corr)
    else:
        b, valid = None, np.broadcast_to(np.True_, images.shape)
    if method is None:
        fit = Fit(b=b)
    else:
        def engine(images_j, lights_j, *, truth_normals=None):
            check_counts(tokens, images_j.shape[0], name, masks)
            thr_j = resolve_thresholds(images_j.shape[0], lights_j, overrides, masks=masks)
            return run(images_j, lights_j, tokens=tokens, options=options, seed=seed,
                       thresholds=thr_j, object_mask=object_mask, overrides=overrides,
                       truth=truth_normals, masks=masks)

        scale = ctx.scale if ctx.ranges is not None else (lambda: _measure(ctx)["scale"])
        problem = Problem(work, lights, valid, object_mask, mask=name, thresholds=thresholds,
                          scale=scale, seed=seed, truth_normals=truth, _start=b, engine=engine)
        fit = method.func(problem, options)
        timer.lap(method.name)
        for key, t in fit.timings.items():
            timer.t[key] = timer.t.get(key, 0.0) + t
    plain = masked and not tokens and fit.b is b and fit.valid is None and not options.weighted
    b, weights = np.asarray(fit.b, dtype=np.float32), fit.weights
    if np.ndim(fit.iterations):  # per-pixel counts: the map goes to info, the max to Result
        info["iterations"] = fit.iterations
    if fit.valid is not None:
        valid = fit.valid
    if masked and options.weighted:
        smin = options.sigma_min if options.sigma_min is not None else 0.01 * ctx.scale
        out = weights if (weights is not None and weights.dtype == np.float32
                          and weights.shape == images.shape) else None
        weights = weighted_masks(work, ctx.S, b, valid, sigma_min=smin, out=out,
                                 dilate_radius=options.dilate_radius,
                                 smooth_sigma=options.smooth_sigma,
                                 kernel_size=options.kernel_size)
        timer.lap("weights")
        b = kernel.wls(work, ctx.S, weights)
        timer.lap("weighted_ps")
    residual = fit.residual
    if residual is None and work is not images:  # the residual of the images solved
        residual = kernel.residual_norm(work, b, ctx.S32, None if valid.all() else valid)
    extra = fit.info.get("warnings") or []
    info.update({key: v for key, v in fit.info.items() if key != "warnings"})
    info["warnings"].extend(w for w in extra if w not in info["warnings"])
    if masked and not plain:
        info["changed"] = changed
    normal = masked and any(s.stage == "normal" for s in specs)
    return _finite(finish(ctx, b, valid, weights, timer=timer, name=name,
                  method=method.name if method is not None else "ps",
                  iterations=rounds if normal else int(np.max(fit.iterations, initial=0)),
                  info=info,
                  want_height=want_height, truth=truth, ne=ne, plain=plain,
                  residual=residual, ring_weights=fit.ring_weights, fields=fit.fields,
                  result_type=fit.result_type, converged=info.get("converged", fit.converged)),
                   images, lights)


def _finite(res, images, lights):
    """Finite outputs or an error: albedo rho = |I| / mu beyond float32's range (or a
    method that diverged) must not pass as a result."""
    bad = ~np.isfinite(res.albedo) | ~np.isfinite(res.normals).all(axis=-1)
    if bad.any():
        p = np.asarray(lights.power, dtype=float)
        raise PsbenchError(
            f"solve: the normals / albedo are not finite at {int(bad.sum())} pixel(s): images "
            f"up to {float(np.abs(images).max()):.3g} under light powers {p.min():.3g}..{p.max():.3g} "
            "give albedos beyond float32's range; rescale the images or the light powers")
    return res


def _measure(ctx):
    """Measure ``ctx.ranges`` (warns once when every image is constant)."""
    o = ctx.options
    rg = ranges(ctx.images, scope=o.th_scope, object_mask=ctx.region, offset=bool(o.th_offset))
    if float(np.max(rg["rng_up"])) <= 0.0:
        msg = ("images have zero dynamic range (every image constant); range-based masks "
               "mask nothing")
        if not ctx.images.any():
            msg = "all images are zero: normals (0, 0, 1), albedo 0"
        warnings.warn(msg, RuntimeWarning, stacklevel=4)
        ctx.warnings.append(msg)
    ctx.ranges = rg
    return rg


def _and(a, b):
    a &= b
    return a


def _masked_ps(ctx, specs, timer, truth, ne):
    """Steps 3-6 of Fig. 3.1 -> (b, valid, rounds, converged or None, changed, corr);
    ``corr`` is None, or (a mask corrected the images) a dict of ``images`` (the
    corrected images solved), ``correction`` and ``change`` (see :func:`_rounds`)."""
    images = ctx.images
    k, H, W = images.shape
    fusing = [s for s in specs if s.fuses]
    if fusing:
        b, valid = fusing[0].func(images, ctx)
        timer.lap("subsets")
        return b, valid, 0, None, [], None
    if not specs:
        b = kernel.ls(images, ctx.S)
        timer.lap("ps")
        if truth is not None:
            ne.append(mean_error(kernel.split(b)[0], truth, ctx.object_mask))
        return b, np.ones((k, H, W), dtype=bool), 0, None, [], None
    valid_img = None
    for stage, lap in (("subset", "subsets"), ("image", "image_masks")):
        for s in specs:
            if s.stage == stage:
                v = s.func(images, ctx)
                valid_img = v if valid_img is None else _and(valid_img, v)
                timer.lap(lap)
    if valid_img is None:
        valid_img = np.ones((k, H, W), dtype=bool)
    completer = _Completer(images, ctx.S)
    valid = completer(valid_img.reshape(k, -1).copy()).reshape(k, H, W)
    b = kernel.wls(images, ctx.S, valid) if not valid.all() else kernel.ls(images, ctx.S)
    timer.lap("ps")
    if truth is not None:
        ne.append(mean_error(kernel.split(b)[0], truth, ctx.object_mask))
    normal = [s for s in specs if s.stage == "normal"]
    if normal and ctx.options.max_iter > 0:
        pre = [s for s in specs if s.stage in ("subset", "image")]
        return _rounds(ctx, b, valid, valid_img, normal, pre, completer, timer, truth, ne)
    return b, valid, 0, None, [], None


def _local(specs, images, b, ctx, pixels):
    """AND of the local normal masks on flat (k, n) images and (n, 3) b."""
    ctx.cache.clear()
    ctx.pixels = pixels
    v = None
    for s in specs:
        r = s.func(images, b, ctx)
        v = r if v is None else _and(v, r)
    return v


def _rounds(ctx, b, valid, valid_img, normal, pre, completer, timer, truth, ne):
    """PS <-> normal masks until the valid masks stop changing (or repeat an earlier
    state: a cycle), a round changes at most ``iter_tol`` of the object pixels, or
    ``max_iter`` rounds. When a global mask returns a correction, the rounds solve the
    corrected images, the image and subset masks ``pre`` judge them anew each round,
    and the rounds also wait for the normals to settle (``correct_tol``)."""
    images, o = ctx.images, ctx.options
    k, H, W = images.shape
    local = [s for s in normal if s.local]
    glob = [s for s in normal if not s.local]
    flat_img = images.reshape(k, -1)
    work = flat_img  # the images solved (corrected ones once a mask corrects them)
    corr = None  # the correction path's record (None: no mask returned a correction)
    flat_b = b.reshape(-1, 3)  # view into b
    flat_valid = valid.reshape(k, -1)
    if np.shares_memory(flat_valid, valid_img):
        flat_valid = flat_valid.copy()
    flat_vimg = valid_img.reshape(k, -1)
    lv = None  # local-mask validity of every pixel (k, N), kept up to date
    active = None  # pixels whose solution changed in the last round (None = all)
    changed = []
    converged = False
    seen = {_digest(flat_valid)}  # states already visited (cycle detection)
    n_obj = int(ctx.object_mask.sum())
    tol_pix = float(o.iter_tol) * n_obj
    it = 0
    for it in range(1, o.max_iter + 1):
        if local:
            if active is None:
                lv = _local(local, work, flat_b, ctx, None)
            elif active.size:
                lv[:, active] = _local(local, work[:, active], flat_b[active], ctx, active)
        fix, moved = None, None  # this round's correction, pixels whose images it changed
        if glob:
            timer.lap("normal_masks")
            ctx.cache.clear()
            ctx.pixels = None
            new = None
            seen_imgs = images if corr is None else work.reshape(k, H, W)
            for s in glob:
                v = s.func(seen_imgs, b, ctx)
                if isinstance(v, tuple):  # (valid, correction): see base.py, Corrections
                    v, c = v
                    if c is not None:
                        if np.shape(c) != images.shape:
                            raise PsbenchError(f"mask {s.name}: correction must have shape "
                                             f"{images.shape}, got {np.shape(c)}")
                        fix = c if fix is None else fix + c
                v = v.reshape(k, -1)
                timer.lap(s.name.lower())
                new = v if new is None else _and(new, v)
            if lv is not None:
                new &= lv
            if fix is not None or corr is not None:  # solve images - correction from now on
                if corr is None:
                    corr = {"change": [], "correction": None}
                J = flat_img if fix is None else flat_img - fix.reshape(k, -1)
                moved = (J != work).any(axis=0)
                work = J
                corr["correction"] = fix
                completer = _Completer(J.reshape(k, H, W), ctx.S)
                if pre:
                    flat_vimg = _judge(pre, J.reshape(k, H, W), ctx).reshape(k, -1)
                    timer.lap("image_masks")
            new &= flat_vimg
            cols = None
        elif active is None:
            new = lv & flat_vimg
            cols = None
        else:
            cols = active
            new = lv[:, cols] & flat_vimg[:, cols]
        completer(new, cols)
        timer.lap("normal_masks")
        if cols is None:
            diff = (new != flat_valid).any(axis=0)
            n_changed = int(np.count_nonzero(diff))
            if moved is not None:
                diff |= moved
            idx = np.flatnonzero(diff)
            new = new[:, idx]
        else:
            diff = (new != flat_valid[:, cols]).any(axis=0)
            idx = cols[diff]
            new = new[:, diff]
            n_changed = int(idx.size)
        changed.append(n_changed)
        if idx.size == 0:
            converged = True
            it -= 1
            break
        old = flat_valid[:, idx].copy()
        flat_valid[:, idx] = new
        if corr is None:
            key = _digest(flat_valid)
            if key in seen:
                # the masks returned to a state of an earlier round: keep the previous state
                flat_valid[:, idx] = old
                converged = "cycle"
                it -= 1
                break
            seen.add(key)
        b_old = flat_b[idx].copy() if corr is not None else None
        flat_b[idx] = kernel.wls(work[:, idx][:, None, :], ctx.S, new[:, None, :]).reshape(-1, 3)
        active = idx
        timer.lap("ps_iter")
        if truth is not None:
            ne.append(mean_error(kernel.split(b)[0], truth, ctx.object_mask))
        if corr is not None:
            inside = ctx.object_mask.reshape(-1)[idx]
            change = _angles(b_old[inside], flat_b[idx][inside]).sum() / max(n_obj, 1)
            corr["change"].append(float(change))
            if n_changed <= tol_pix and change < o.correct_tol:
                converged = True if n_changed == 0 else "tol"
                break
        elif idx.size <= tol_pix:
            converged = "tol"
            break
    out = None
    if corr is not None:
        fix = corr["correction"]
        out = {"images": work.reshape(k, H, W), "change": corr["change"],
               "correction": np.zeros_like(images) if fix is None else fix}
    return b, flat_valid.reshape(k, H, W), it, converged, changed, out


def _judge(pre, images, ctx):
    """The image and subset masks on corrected images (ranges measured on them when the
    solve measures ranges): AND of their validities, (k, H, W) bool."""
    ctx.cache.clear()
    if ctx.ranges is not None:
        o = ctx.options
        ctx.ranges = ranges(images, scope=o.th_scope, object_mask=ctx.region,
                            offset=bool(o.th_offset))
        ctx._flat = None
    valid = None
    for s in pre:
        v = s.func(images, ctx)
        valid = v if valid is None else _and(valid, v)
    return valid


def _angles(b0, b1):
    """Angles (degrees, float64) between the rows of two (n, 3) arrays of rho n."""
    n0 = np.linalg.norm(b0, axis=1)
    n1 = np.linalg.norm(b1, axis=1)
    c = np.einsum("ij,ij->i", b0, b1, dtype=np.float64) / np.maximum(n0 * n1, 1e-30)
    return np.degrees(np.arccos(np.clip(c, -1.0, 1.0)))


def _digest(valid):
    return hashlib.blake2b(np.packbits(valid).tobytes(), digest_size=16).digest()


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
        # light indices wide enough for any light count
        self.index_type = np.min_scalar_type(max(k - 1, 0))

    def _ensure(self, cols):
        miss = cols[~self.have[cols]]
        if miss.size == 0:
            return
        if self.order is None:
            self.order = np.zeros((self.k, self.flat.shape[1]), dtype=self.index_type)
        sub = self.flat[:, miss]
        r = sub - self.S32 @ (self.P @ sub)
        np.abs(r, out=r)
        self.order[:, miss] = _ck.order(r, self.index_type)
        self.have[miss] = True

    def __call__(self, valid, cols=None):
        """Complete ``valid`` (k, n) in place where short; ``cols`` maps its columns to
        pixel indices (None: all pixels). Returns ``valid``."""
        short, cnt = _ck.short_columns(valid)
        if short.size == 0:
            return valid
        pix = short if cols is None else cols[short]
        self._ensure(pix)
        return _ck.fill(valid, short, cnt, self.order[:, pix])
