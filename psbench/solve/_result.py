"""The :class:`Result` of :func:`psbench.solve` and how it is assembled."""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import kernel
from .base import Lazy

__all__ = ["Result", "Timer", "mean_error", "finish"]


@dataclass(eq=False)
class Result:
    """Output of :func:`psbench.solve`.

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
        Final per-observation WLS weights (weighted masks / FWLSE: normalised so that
        1 = sigma_min); None for binary solves. Always per observation.
    residual : (H, W) float32
        L2 norm of i - rho s.n over the **used** observations (``valid``) of the
        final solution; 0 outside ``object_mask``.
    height : (H, W) float32 or None
        Integrated heights when ``want_height=True``.
    timings : dict
        Stage -> seconds, including "total".
    lights : Layout
    mask : str
        Canonical mask name ("Th-Hi-Re-Sh").
    method : str
    iterations : int
        PS <-> normal-mask rounds when the expression has normal masks, else the
        method's iterations (FWLSE; 0 for "ps"; the largest of a per-pixel count, whose
        map is then ``info["iterations"]``).
    thresholds : dict
        Resolved threshold values actually used.
    info : dict
        Extras: ``th_scope``, ``converged`` (True: no mask changed; "cycle": the
        masks returned to an earlier state; "tol": a round changed at most
        ``iter_tol`` of the object pixels; False: ``max_iter`` reached; FWLSE: its
        own criterion), ``changed`` (pixels whose mask changed per round), ``ne``
        (mean normal error per round when ``truth_normals`` was given), warnings.
    ring_weights : (rings, H, W) float32 or None
        Per-ring fusion weights of WPS (sum 1 per pixel); None otherwise.
    converged : bool, str or (H, W) bool array
        ``info["converged"]`` when the mask rounds or the method set it, else the
        method's verdict (``Fit.converged``).
    ve : Validation
        Ground-truth-free validation error (:mod:`psbench.solve.validation`): per-pixel
        map ``ve.map`` (H, W) and ``ve.mean`` / ``ve.median``; the held-out errors of
        the Lambertian fit over the observations the solve used (``weights``, else
        ``valid``). Computed when first read.
    fallback : (H, W) bool or None
        Pixels where the method's richer fit did not predict the held-out observations
        better than the simpler answer it started from and fell back to it
        (:mod:`psbench.solve.fallback`; ``robust``: to the trimmed fit, ``tsfit``: to
        its start); False outside ``object_mask``. None: the method has no fallback
        (or it was switched off).
    """

    normals: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    weights: np.ndarray | None
    residual: np.ndarray = Lazy()
    height: np.ndarray | None
    timings: dict
    lights: object
    mask: str
    method: str
    iterations: int = 0
    thresholds: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)
    ring_weights: np.ndarray | None = None
    converged: Any = True
    ve: Any = Lazy(None)
    fallback: Any = None

    @property
    def b(self) -> np.ndarray:
        """rho * n, (H, W, 3) float32."""
        return self.normals * self.albedo[..., None]

    def __repr__(self) -> str:
        H, W = self.albedo.shape
        return (f"Result(mask={self.mask!r}, method={self.method!r}, k={self.valid.shape[0]}, "
                f"size={H}x{W}, iterations={self.iterations}, "
                f"total={self.timings.get('total', float('nan')):.3f}s)")


class Timer:
    """Stage timings: ``lap(name)`` adds the time since the previous lap to ``name``."""

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


def mean_error(normals, truth, object_mask):
    """Mean angle (degrees) between unit normals over ``object_mask`` (diagnostics)."""
    if not object_mask.any():
        return 0.0
    # einsum's sums, by components and in place (~3x faster on (H, W, 3))
    d = np.multiply(normals[..., 0], truth[..., 0])
    tmp = np.multiply(normals[..., 1], truth[..., 1])
    d += tmp
    np.multiply(normals[..., 2], truth[..., 2], out=tmp)
    d += tmp
    np.clip(d, -1.0, 1.0, out=d)
    a = d.reshape(-1) if object_mask.all() else d[object_mask]
    np.arccos(a, out=a)
    return float(np.degrees(a, out=a).mean())


def finish(ctx, b, valid, weights, *, timer, name, method, iterations, info, want_height,
           truth=None, ne=None, plain=False, residual=None, ring_weights=None, fields=None,
           result_type=None, converged=True):
    """Split b, compute the residual, clear the outside of the object, integrate.

    ``plain``: b is the unmasked least-squares solution; its residual is then computed
    exactly when first read (it costs as much as the solve, and few callers read it).
    """
    images, omask, full = ctx.images, ctx.object_mask, ctx.full
    normals, albedo = kernel.split(b)
    if not info["warnings"] and not albedo.any() and not images.any():
        # (checked on the albedo first: a full pass over the images only when needed)
        msg = "all images are zero: normals (0, 0, 1), albedo 0"
        warnings.warn(msg, RuntimeWarning, stacklevel=5)
        info["warnings"].append(msg)
    timer.lap("split")
    if truth is not None and not plain:
        ne.append(mean_error(normals, truth, omask))
    if ne is not None:
        info["ne"] = ne
    out = None if full else ~omask
    if plain:
        S32 = ctx.S32

        def resid():
            r = kernel.ls_residual_norm(images, S32)
            if out is not None:
                r[out] = 0.0
            return r
    else:
        resid = residual if residual is not None else kernel.residual_norm(
            images, b, ctx.S32, None if valid.all() else valid)
        if out is not None:
            resid[out] = 0.0
        timer.lap("residual")
    if not full:
        normals[out] = (0.0, 0.0, 1.0)
        albedo[out] = 0.0
        if not valid[:, out].all():
            valid[:, out] = True
        if weights is not None:
            weights[:, out] = 0.0
    height = None
    if want_height:
        from ..integrate.poisson import integrate
        height = np.asarray(integrate(normals, object_mask=ctx.region, integrator=ctx.options.integrator),
                            dtype=np.float32)
        timer.lap("height")
    kw = dict(normals=normals, albedo=albedo, valid=valid, weights=weights, residual=resid,
              height=height, lights=ctx.lights, mask=name, method=method,
              iterations=int(iterations), thresholds=ctx.thresholds, info=info,
              ring_weights=ring_weights, converged=converged)
    kw.update(fields or {})
    res = (result_type or Result)(timings=timer.done(), **kw)
    if "ve" not in kw:
        def ve():  # the held-out errors cost about one solve: only when read
            from .validation import validate
            return validate(images, ctx.S, res.weights if res.weights is not None else res.valid,
                            object_mask=omask)
        res.ve = ve
    return res
