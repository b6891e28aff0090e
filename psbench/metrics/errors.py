"""Error measures of thesis Section 2.6: NE (Eq. 2.28), IE (Eqs. 2.29-2.31), QF (Eq. 2.32).

Definitions chosen where the thesis leaves room (all documented per function):

* **NE** – angle between estimated and true normal, ``atan2(|a x b|, a . b)`` in
  float64 (accurate at small angles, independent of vector lengths), averaged
  over the object mask.
* **IE** – per pixel, the residual ``R_i = I_i - rho s_i . n`` of every image
  i = 1..k with the *linear* Lambert prediction (no clamp at 0), which is the
  least-squares residual of Eq. 2.31 when ``rho n`` is the unmasked LS solution.
  Eq. 2.29 averages over images, so the per-pixel norms are normalised by the
  image count: ``l1 = mean_i |R_i|``, ``l2 = sqrt(mean_i R_i^2)`` (RMS),
  ``linf = max_i |R_i|``; these are in intensity units and comparable across k
  (``average=False`` gives the plain vector norms of Eq. 2.31's text). IE is the
  mean of the per-pixel values over the object mask.
* **Weighted IE** (Eq. 2.30) – ``IE = sum_j w_j IE_j`` per pixel, with ring
  weights ``w_j`` (rings, H, W) and per-ring IE maps, then averaged over the object
  mask.
* **QF** – ``TP / (TP + FP + FN)`` counted over observations (k x object pixels);
  see :func:`quality_factor` for the highlight / shadow / total split (defined in
  ``psbench._quality``, exported here).
"""
from __future__ import annotations

import numpy as np

from .._shared.checks import PsbenchError, as_mask, as_S, choice
from .._shared.deprecation import renamed_args
from .quality import quality_counts, quality_factor

__all__ = [
    "normal_error_map", "normal_error", "normal_error_stats", "ne_by_zenith",
    "intensity_error", "intensity_error_map", "weighted_intensity_error", "ie_relative",
    "dynamic_range", "quality_factor", "quality_counts", "NORMS",
]

#: per-pixel norms across images accepted by :func:`intensity_error`
NORMS = ("l1", "l2", "linf")


# ----------------------------------------------------------------------------- helpers
def _normals(a, name, shape=None):
    arr = np.asarray(a)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise PsbenchError(f"{name} must have shape (H, W, 3), got {arr.shape}")
    if shape is not None and arr.shape[:2] != tuple(shape):
        raise PsbenchError(
            f"{name} must have shape {tuple(shape) + (3,)} to match, got {arr.shape}")
    if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
        raise PsbenchError(f"{name} must be a real numeric array, got dtype {arr.dtype}")
    if not np.isfinite(arr).all():
        raise PsbenchError(f"{name} holds NaN/inf values")
    return arr


def _mean_over(values, object_mask):
    v = values[object_mask] if object_mask is not None else values.ravel()
    return float(v.mean()) if v.size else float("nan")


def _region(object_mask, shape):
    """The object mask as (H, W) bool, or None for all pixels."""
    return None if object_mask is None else as_mask(object_mask, shape, "object_mask")


# ----------------------------------------------------------------------------- NE
def normal_error_map(normals, truth):
    """Angle between two normal maps, per pixel.

    Parameters
    ----------
    normals, truth : (H, W, 3) array_like
        Need not be unit length (the angle is scale invariant). A zero vector
        gives an angle of 0 with anything (atan2(0, 0)); avoid them.

    Returns
    -------
    error : (H, W) float64
        Degrees in [0, 180], ``atan2(|a x b|, a . b)`` computed in float64.
    """
    a = _normals(normals, "normals").astype(np.float64, copy=False)
    b = _normals(truth, "truth", shape=a.shape[:2]).astype(np.float64, copy=False)
    cross = np.cross(a, b)
    s = np.sqrt(np.einsum("...i,...i->...", cross, cross))
    c = np.einsum("...i,...i->...", a, b)
    return np.degrees(np.arctan2(s, c))


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def normal_error(normals, truth, *, object_mask=None):
    """Mean angular normal error in degrees over the object (Eq. 2.28).

    Parameters
    ----------
    normals, truth : (H, W, 3) array_like
    object_mask : (H, W) bool, optional
        Pixels to average over; None = all. An empty mask gives NaN.

    Returns
    -------
    float
    """
    e = normal_error_map(normals, truth)
    return _mean_over(e, _region(object_mask, e.shape))


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def normal_error_stats(normals, truth, *, object_mask=None):
    """Summary statistics of the angular error over the object.

    Parameters
    ----------
    normals, truth : (H, W, 3) array_like
    object_mask : (H, W) bool, optional
        Pixels to count; None = all.

    Returns
    -------
    dict
        ``mean``, ``median`` (degrees) and ``lt5``, ``lt10``, ``lt20``: fractions
        (0..1) of object pixels whose error is strictly below 5, 10, 20 degrees.
        All NaN for an empty mask.
    """
    e = normal_error_map(normals, truth)
    m = _region(object_mask, e.shape)
    v = e[m] if m is not None else e.ravel()
    if v.size == 0:
        nan = float("nan")
        return dict(mean=nan, median=nan, lt5=nan, lt10=nan, lt20=nan)
    return dict(mean=float(v.mean()), median=float(np.median(v)),
                lt5=float((v < 5).mean()), lt10=float((v < 10).mean()),
                lt20=float((v < 20).mean()))


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def ne_by_zenith(normals, truth, *, object_mask=None, bins=None):
    """Mean NE versus the true surface zenith (thesis Fig. 4.9).

    Parameters
    ----------
    normals, truth : (H, W, 3) array_like
    object_mask : (H, W) bool, optional
        Pixels to count; None = all.
    bins : int or 1-D array_like of edges in degrees, optional
        Default: 5-degree bins from 0 to 90. An int gives that many equal bins
        over [0, 90]. Pixels with zenith outside the edges are dropped; the
        last bin includes its right edge.

    Returns
    -------
    pandas.DataFrame
        One row per bin: ``zenith`` (bin centre, deg), ``lo``, ``hi`` (edges),
        ``ne`` (mean NE in deg, NaN for an empty bin), ``count`` (pixels).
    """
    import pandas as pd

    e = normal_error_map(normals, truth)
    t = np.asarray(truth, dtype=np.float64)
    tz = t[..., 2] / np.maximum(np.linalg.norm(t, axis=-1), 1e-300)
    zen = np.degrees(np.arccos(np.clip(tz, -1.0, 1.0)))
    m = as_mask(object_mask, e.shape, "object_mask")
    if bins is None:
        edges = np.linspace(0.0, 90.0, 19)
    elif np.isscalar(bins):
        if int(bins) < 1:
            raise PsbenchError(f"bins must be a positive int or edges, got {bins}")
        edges = np.linspace(0.0, 90.0, int(bins) + 1)
    else:
        edges = np.asarray(bins, dtype=np.float64)
        if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
            raise PsbenchError(f"bins must be increasing edges (>= 2), got {bins!r}")
    zv, ev = zen[m], e[m]
    idx = np.searchsorted(edges, zv, side="right") - 1
    idx[zv == edges[-1]] = edges.size - 2
    ok = (idx >= 0) & (idx < edges.size - 1)
    nb = edges.size - 1
    count = np.bincount(idx[ok], minlength=nb)
    total = np.bincount(idx[ok], weights=ev[ok], minlength=nb)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return pd.DataFrame({"zenith": 0.5 * (edges[:-1] + edges[1:]), "lo": edges[:-1],
                         "hi": edges[1:], "ne": mean, "count": count.astype(np.int64)})


# ----------------------------------------------------------------------------- IE
def _b_and_S(result, lights, k, shape):
    """Albedo-scaled normals (H, W, 3) float64 and S (k, 3) from a result or array."""
    if hasattr(result, "normals"):
        n = _normals(result.normals, "result.normals", shape)
        alb = getattr(result, "albedo", None)
        if alb is None:
            raise PsbenchError("result has .normals but no .albedo; pass b = rho*n instead")
        alb = np.asarray(alb, dtype=np.float64)
        if alb.shape != tuple(shape):
            raise PsbenchError(f"result.albedo must have shape {tuple(shape)}, got {alb.shape}")
        b = n.astype(np.float64) * alb[..., None]
        if lights is None:
            lights = getattr(result, "lights", None)
    else:
        b = _normals(result, "result", shape).astype(np.float64)
    if lights is None:
        raise PsbenchError("lights are required when result has no .lights")
    return b, as_S(lights, k)


def _norm(R, norm, average, axis=0):
    if norm == "l1":
        v = np.abs(R).sum(axis=axis)
        return v / R.shape[axis] if average else v
    if norm == "l2":
        v = np.einsum("k...,k...->...", R, R) if axis == 0 else (R * R).sum(axis=axis)
        return np.sqrt(v / R.shape[axis] if average else v)
    return np.abs(R).max(axis=axis)


def intensity_error_map(images, result, lights=None, *, norm="l2", clamp=False,
                        valid=None, average=True):
    """Per-pixel intensity error: the norm across images of the Lambert residual.

    Parameters
    ----------
    images : (k, H, W) array_like
    result : Result-like or (H, W, 3) array_like
        An object with ``.normals``, ``.albedo`` (and ``.lights``), or the
        albedo-scaled normals ``b = rho * n``.
    lights : Layout or (k, 3) array_like, optional
        Illumination (``Layout.S`` = power * direction). Overrides ``result.lights``.
    norm : {"l1", "l2", "linf"}
    clamp : bool
        False (default): linear prediction ``s . b`` (Eq. 2.31's LS residual).
        True: ``max(0, s . b)`` (attached-shadow aware).
    valid : (k, H, W) bool, optional
        Observations to include (True = used); None = all k images. Pixels with
        no valid observation get 0.
    average : bool
        True (default): normalise by the number of images (mean |R|, RMS, max).
        False: plain vector norms (sum |R|, sqrt(sum R^2), max).

    Returns
    -------
    ie : (H, W) float64
    """
    from .._shared.checks import as_images

    imgs = as_images(images, "images")
    k, H, W = imgs.shape
    choice(norm, NORMS, "norm")
    if valid is not None:
        v = np.asarray(valid)
        if v.shape != (k, H, W):
            raise PsbenchError(f"valid must have shape {(k, H, W)}, got {v.shape}")
        v = v.astype(bool, copy=False)
    b, S = _b_and_S(result, lights, k, (H, W))
    pred = (S @ b.reshape(-1, 3).T).reshape(k, H, W)  # linear Lambert prediction
    if clamp:
        np.maximum(pred, 0.0, out=pred)
    R = np.subtract(imgs, pred, out=pred)
    if valid is None:
        return _norm(R, norm, average)
    R = np.where(v, R, 0.0)
    cnt = v.sum(axis=0)
    if norm == "linf":
        return np.abs(R).max(axis=0)
    out = _norm(R, norm, False)
    if average:
        scale = np.where(cnt > 0, 1.0 / np.maximum(cnt, 1), 0.0)
        out = out * scale if norm == "l1" else out * np.sqrt(scale)
    return out


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def weighted_intensity_error(ring_ie, weights, *, object_mask=None, per_pixel=False):
    """Weighted IE of Eq. 2.30: ``sum_j w_j IE_j`` per pixel, mean over the object.

    Parameters
    ----------
    ring_ie : (rings, H, W) array_like
        Per-ring IE maps (e.g. from :func:`intensity_error_map` on each ring's
        images with that ring's solution).
    weights : (rings, H, W) array_like
        Ring weights per pixel (normally summing to 1 over rings).
    object_mask : (H, W) bool, optional
        Pixels to average over; None = all.
    per_pixel : bool
        Return the (H, W) map instead of its mean.
    """
    r = np.asarray(ring_ie, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    if r.ndim != 3:
        raise PsbenchError(f"ring_ie must have shape (rings, H, W), got {r.shape}")
    if w.shape != r.shape:
        raise PsbenchError(f"weights must have shape {r.shape} like ring_ie, got {w.shape}")
    if not (np.isfinite(r).all() and np.isfinite(w).all()):
        raise PsbenchError("ring_ie and weights must be finite")
    ie = np.einsum("jhw,jhw->hw", w, r)
    if per_pixel:
        return ie
    return _mean_over(ie, _region(object_mask, ie.shape))


def _ring_ies(images, result, lights, weights, norm, clamp, average):
    """Per-ring IE maps for Eq. 2.30."""
    imgs = np.asarray(images)
    k, H, W = imgs.shape
    if lights is None:
        lights = getattr(result, "lights", None)
    if lights is None or not hasattr(lights, "rings"):
        raise PsbenchError("weights (rings, H, W) need lights as a Layout (ring ids); "
                           "pass lights=Layout or a result with .lights")
    rings = lights.rings()
    w = np.asarray(weights)
    if w.ndim != 3 or w.shape != (len(rings), H, W):
        raise PsbenchError(
            f"weights must have shape {(len(rings), H, W)} (rings, H, W), got {w.shape}")
    ring_n = getattr(result, "ring_normals", None)
    ring_a = getattr(result, "ring_albedo", None)
    S = as_S(lights, k)
    out = np.empty((len(rings), H, W))
    for j, idx in enumerate(rings):
        if ring_n is not None and ring_a is not None:
            b = np.asarray(ring_n[j], dtype=np.float64) * np.asarray(ring_a[j])[..., None]
        elif ring_n is not None:
            # ring normals without ring albedo: use the fused albedo
            b = np.asarray(ring_n[j], dtype=np.float64) * np.asarray(result.albedo)[..., None]
        else:
            b, _ = _b_and_S(result, S, k, (H, W))
        out[j] = intensity_error_map(imgs[idx], b, S[idx], norm=norm, clamp=clamp,
                                     average=average)
    return out, w


@renamed_args(renamed={"mask": "object_mask"})
def intensity_error(images, result, lights=None, *, norm="l2", object_mask=None, weights=None,
                    per_pixel=False, clamp=False, valid=None, average=True):
    """Intensity error (Eqs. 2.29-2.31), mean over the object.

    Parameters
    ----------
    images : (k, H, W) array_like
    result : Result-like or (H, W, 3) array_like
        Object with ``.normals``, ``.albedo``, ``.lights`` or ``b = rho * n``.
    lights : Layout or (k, 3), optional
        Overrides ``result.lights``; required for an array ``result``.
    norm : {"l1", "l2", "linf"}
        Norm across images per pixel (normalised by the image count unless
        ``average=False``; see the module docstring).
    object_mask : (H, W) bool, optional
        Pixels to average over; None = all. Empty mask -> NaN.
    weights : (rings, H, W) array_like, optional
        Weighted IE (Eq. 2.30): per-ring IE maps are computed from each ring's
        images (ring ids from the Layout) with the ring's own solution when the
        result carries ``.ring_normals`` (+ ``.ring_albedo``), otherwise with the
        fused ``rho n``, and combined as ``sum_j w_j IE_j``.
    per_pixel : bool
        Return the (H, W) map instead of its mean.
    clamp : bool
        Clamp the Lambert prediction at 0 (default False: linear, Eq. 2.31).
    valid : (k, H, W) bool, optional
        Only these observations enter the norm (ignored with ``weights``).
    average : bool
        Normalise norms by the image count (default True).

    Returns
    -------
    float or (H, W) float64
    """
    if weights is not None:
        ring_ie, w = _ring_ies(images, result, lights, weights, norm, clamp, average)
        ie = weighted_intensity_error(ring_ie, w, per_pixel=True)
    else:
        ie = intensity_error_map(images, result, lights, norm=norm, clamp=clamp,
                                 valid=valid, average=average)
    if per_pixel:
        return ie
    return _mean_over(ie, _region(object_mask, ie.shape))


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def dynamic_range(images, *, object_mask=None):
    """Mean over images of each image's range (max - min over the object).

    Parameters
    ----------
    images : (k, H, W) array_like
    object_mask : (H, W) bool, optional
        Pixels the range is taken over; None = all. Empty mask -> NaN.

    Returns
    -------
    float
    """
    from .._shared.checks import as_images

    imgs = as_images(images, "images")
    m = as_mask(object_mask, imgs.shape[1:], "object_mask")
    if not m.any():
        return float("nan")
    v = imgs[:, m]
    return float((v.max(axis=1) - v.min(axis=1)).astype(np.float64).mean())


_image_range = dynamic_range  # ie_relative's keyword shadows the name


@renamed_args(renamed={"mask": "object_mask"})
def ie_relative(images, result, lights=None, *, object_mask=None, dynamic_range=None,
                **kwargs):
    """IE as a percentage of the mean image dynamic range.

    ``100 * intensity_error(...) / range``; keyword arguments are passed to
    :func:`intensity_error`. With ``per_pixel=True`` returns the (H, W) map in
    percent. NaN when the range is not positive.

    Parameters
    ----------
    dynamic_range : float or (k,) array_like, optional
        The range to divide by (its mean for an array), e.g. a Scene's
        ``dynamic_range`` of the clean images. Default: :func:`dynamic_range`
        of ``images`` over the object mask (max - min of each image, averaged).
    """
    ie = intensity_error(images, result, lights, object_mask=object_mask, **kwargs)
    if dynamic_range is None:
        dr = _image_range(images, object_mask=object_mask)
    else:
        dr = np.asarray(dynamic_range, dtype=np.float64)
        if dr.ndim > 1 or dr.size == 0:
            raise PsbenchError(
                f"dynamic_range must be a number or a (k,) array, got shape {dr.shape}")
        dr = float(dr.mean())
    if not dr > 0:
        return ie * np.nan if kwargs.get("per_pixel") else float("nan")
    return 100.0 * ie / dr
