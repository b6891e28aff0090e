"""Ground-truth-free validation of a solve: how well it predicts observations it did not fit.

Per pixel, each observation the fit used is predicted by the fit made without it
(leave-one-light-out: k-fold over the lights with folds of one light, computed in
closed form as a rank-1 downdate of the pixel's 3 x 3 normal equations, see
:mod:`psbench.solve._heldout_kernel`); an observation the fit did not use (shadowed,
masked, rejected) is not part of the validation, exactly as the method excludes it.

The validation error of a pixel is

    ve = median_i |e_i| / s,

the median absolute held-out error over the pixel's used observations, relative to
the pixel's intensity scale s, the mean of all its k observations (independent of the
method, so that methods are compared on one scale; floored at 1e-6 times the mean of
the object). The median makes ve robust to the few observations a fit explains badly
(a highlight the Lambertian fit kept); a pixel with fewer than 4 used observations, or
whose held-out errors are all undefined, has ve = NaN. Summaries are the mean and the
median of the map over the object pixels where it is defined.

The Lambertian validation serves the masks and the Lambertian robust solvers (the
weighted least-squares fit over the method's final weights is their solution);
:func:`ts_heldout` gives the held-out errors of the Lambert + Torrance-Sparrow model
to first order (its per-pixel unknowns rho * n, the lobe held at its fitted value).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._shared.checks import PsbenchError
from . import _heldout_kernel as _hk

__all__ = ["Validation", "lambert_heldout", "ts_heldout", "validation_map", "validate"]

#: pixels per block (bounds the (k, block) temporaries)
BLOCK = 1 << 16


@dataclass(eq=False)
class Validation:
    """The validation error of a solve (see :mod:`psbench.solve.validation`).

    Attributes
    ----------
    map : (H, W) float32
        Per-pixel validation error, relative to the pixel's intensity scale; NaN off
        the object and where it is undefined.
    mean, median : float
        Over the object pixels where ``map`` is defined (NaN if none).
    defined : float
        Fraction of the object pixels where ``map`` is defined.
    """

    map: np.ndarray
    mean: float
    median: float
    defined: float

    def __repr__(self):
        return (f"Validation(mean={self.mean:.4g}, median={self.median:.4g}, "
                f"defined={self.defined:.3f})")


def _w(w):
    w = np.ascontiguousarray(w)
    return w.view(np.uint8) if w.dtype == bool else w.astype(np.float32, copy=False)


def lambert_heldout(I, S, w, *, median=False):
    """Held-out errors (k, n) float32 of the weighted Lambertian fit of each pixel.

    Parameters
    ----------
    I : (k, n) float32
        Observations of n pixels.
    S : (k, 3) array_like
        Light vectors (direction times power).
    w : (k, n) float32 or bool
        The fit's weights (> 0: used).
    median : bool
        Also return the median |e_i| over each pixel's used observations (the
        ``median`` of :func:`validation_map`, computed in the same pass).

    Returns
    -------
    (k, n) float32
        e_i = i - predicted i by the fit without observation i for used observations,
        the plain residual for unused ones; NaN where undefined.
    (n,) float32, only with ``median``
    """
    I = np.ascontiguousarray(I, dtype=np.float32)
    out = np.empty_like(I)
    med = np.empty(I.shape[1] if median else 0, dtype=np.float32)
    _hk.lambert_errors(I, np.ascontiguousarray(S, dtype=np.float64), _w(w), out, med)
    return (out, med) if median else out


def ts_heldout(I, table, w, n, rd, rs, m, *, median=False):
    """Held-out errors (k, p) float32 of a Lambert + Torrance-Sparrow fit, to first order.

    ``table`` is :attr:`psbench.solve.methods.tsfit._lm.Lights.table`; ``n`` (3, p) unit
    normals; ``rd``, ``rs``, ``m`` (p,) the fitted rho_d, rho_s and lobe width;
    ``median`` as in :func:`lambert_heldout`."""
    I = np.ascontiguousarray(I, dtype=np.float32)
    out = np.empty_like(I)
    med = np.empty(I.shape[1] if median else 0, dtype=np.float32)
    # always a fresh writable copy (p floats): numba compiles read-only arrays separately
    f = lambda a: np.array(np.broadcast_to(np.asarray(a, np.float32),  # noqa: E731
                                           (I.shape[1],)))
    _hk.ts_errors(table, I, _w(w), np.ascontiguousarray(n, dtype=np.float32), f(rd), f(rs),
                  f(m), out, med)
    return (out, med) if median else out


def intensity_floor(I):
    """The floor of the pixels' intensity scales in :func:`validation_map`: 1e-6 times
    the mean of the mean observations of the pixels of ``I`` (k, n)."""
    return _floor(I.mean(axis=0, dtype=np.float64))


def _floor(s):
    return 1e-6 * max(float(s.mean()), 1e-30)


def validation_map(e, used, I, *, median=None, floor=None):
    """Per-pixel validation error (n,) float32: median |e| over the used observations
    divided by the pixel's mean observation (see the module docstring).

    ``median`` (n,) float32: that median when the held-out pass computed it
    (``lambert_heldout(..., median=True)``); ``e`` is then not read. ``floor``
    (float or (n,)): the intensity floor when ``I`` holds only some of the pixels it
    is to be taken over (:func:`intensity_floor` of those); default: that of ``I``."""
    used = np.ascontiguousarray(np.asarray(used) > 0)
    cnt = used.sum(axis=0)
    if median is not None:
        med = np.asarray(median, dtype=np.float32)
    else:
        med = np.empty(used.shape[1], dtype=np.float32)
        _hk.abs_median(np.ascontiguousarray(e, dtype=np.float32), used.view(np.uint8), med)
    s = I.mean(axis=0, dtype=np.float64)
    if floor is None:
        floor = _floor(s)
    out = (med / np.maximum(s, floor)).astype(np.float32)
    out[cnt < 4] = np.nan
    return out


def validate(images, lights, weights, *, object_mask=None) -> Validation:
    """The Lambertian validation error of a solve.

    Parameters
    ----------
    images : (k, H, W) float32
    lights : (k, 3) array_like or Layout
        Light vectors (``Layout.S``).
    weights : (k, H, W) float32 or bool
        The observations the solve used (``Result.weights`` when not None, else
        ``Result.valid``).
    object_mask : (H, W) bool, optional

    Returns
    -------
    Validation
    """
    images = np.asarray(images)
    if images.ndim != 3:
        raise PsbenchError(f"images must be (k, H, W), got shape {images.shape}")
    k, H, W = images.shape
    S = np.asarray(getattr(lights, "S", lights), dtype=np.float64)
    if S.shape != (k, 3):
        raise PsbenchError(f"lights must be ({k}, 3) for {k} images, got {S.shape}")
    weights = np.asarray(weights)
    if weights.shape != images.shape:
        raise PsbenchError(f"weights must have the images' shape {images.shape}, got "
                           f"{weights.shape}")
    om = np.ones((H, W), bool) if object_mask is None else np.asarray(object_mask, bool)
    idx = np.flatnonzero(om.reshape(-1))
    flat, wflat = images.reshape(k, -1), weights.reshape(k, -1)
    vals = np.empty(idx.size, dtype=np.float32)
    for lo in range(0, idx.size, BLOCK):
        sel = idx[lo:lo + BLOCK]
        I = np.ascontiguousarray(flat[:, sel], dtype=np.float32)
        w = np.ascontiguousarray(wflat[:, sel])
        e, med = lambert_heldout(I, S, w, median=True)
        vals[lo:lo + sel.size] = validation_map(e, w, I, median=med)
    return summarise(vals, idx, (H, W))


def summarise(vals, idx, shape) -> Validation:
    """A :class:`Validation` from per-pixel values ``vals`` at flat indices ``idx``."""
    out = np.full(shape[0] * shape[1], np.nan, dtype=np.float32)
    out[idx] = vals
    ok = np.isfinite(vals)
    mean = float(vals[ok].mean()) if ok.any() else float("nan")
    med = float(np.median(vals[ok])) if ok.any() else float("nan")
    return Validation(map=out.reshape(shape), mean=mean, median=med,
                      defined=float(ok.mean()) if vals.size else 0.0)
