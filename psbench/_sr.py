"""SR, the secondary-reflection normal mask (thesis Section 8.3), as pure functions.

The thesis proposes "a mask working similar to the ray tracing algorithm", iterated
inside unified PS because removing observations changes the normals and so the
traced light. psbench's SR step:

1. from the current solution b = rho n: normals, albedo, and heights integrated
   from the normals (or given);
2. predict the light every observation receives from other surface points by the
   ray casting of :mod:`psbench._interreflect` (the same quadrature the renderer
   uses), with the *predicted* direct Lambert images as emitters
   (``source="model"``: ``rho (s.n)`` where s.n > 0 and not cast-shadowed on the
   integrated heights) or the observed images (``source="images"``, Lambertian
   emitters, all bounces at once; observations outside ``valid`` replaced by the
   model); on a grid of at most ``size`` pixels a side (the secondary light is
   smooth), upsampled, times the full-resolution albedo;
3. mask the observations whose predicted secondary fraction ``f = S / I`` exceeds
   ``t_sr`` (or weight them by ``(1 - f)^2``, the squared share of direct light), and
   -- unless ``correct=False`` -- subtract the predicted secondary light from the
   observations kept;
4. re-solve, repeat until the normals stop moving.

Why the subtraction: on a Lambertian concave surface the one-bounce light of a lit
observation is ``c_i(p) = rho(p) sum_q K(p, q) rho(q) (s_i . n_q)``, linear in s_i,
so a lit observation reads ``s_i . (rho n + sum_q K rho rho_q n_q)``: a *consistent*
pseudo-normal (a spherical cup: exactly ``rho n + kappa z``). Masking alone cannot
see it -- every lit observation agrees on the wrong normal -- and only helps where the
secondary light dominates (shadowed observations, f = 1). The subtraction, the
iteration of Nayar, Ikeuchi and Kanade's "shape from interreflections", removes it.
``correct=False`` is the literal mask of the thesis, kept for comparison.

Limits (measured, ``benchmarks/bench_interreflect.py``): the prediction is
Lambertian. On Torrance-Sparrow images SR alone is worse than plain least squares
(highlights inflate the albedo it predicts from, and it over-subtracts); it needs the
highlight masks first (``mask="Th-Hi-Re-Sh"``). On images without interreflection it
subtracts light that is not there. ``bounces`` should match the world: a prediction
of one bounce leaves the second uncorrected, and vice versa.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from ._checks import PsbenchError, as_images, as_mask
from ._interreflect import secondary
from .shadowmap import shadow_map
from .solve import kernel

__all__ = ["predict", "sr_valid", "sr_weights", "solve_sr", "Prediction", "SRFit", "SOURCES"]

SOURCES = ("model", "images")


@dataclass(eq=False)
class Prediction:
    """Predicted secondary light.

    Attributes
    ----------
    secondary : (k, H, W) float32
        Predicted secondary light per observation (image units), 0 off the object.
    fraction : (k, H, W) float32
        ``secondary / images`` clipped to [0, 1] (1 where the observation is <= 0 and
        light is predicted); None when no images were given.
    height : (H, W) float32
        Heights used (integrated or given), pixel units.
    """

    secondary: np.ndarray
    fraction: np.ndarray | None
    height: np.ndarray


@dataclass(eq=False)
class SRFit:
    """Result of :func:`solve_sr`: ``b`` (H, W, 3), ``normals``, ``albedo``, ``valid``
    (k, H, W) bool, ``weights`` (k, H, W) float32 or None, the last ``prediction``,
    ``iterations``, ``converged`` and ``info`` (``change`` per round in degrees,
    ``ne`` per round when truth was given, ``timings``)."""

    b: np.ndarray
    normals: np.ndarray
    albedo: np.ndarray
    valid: np.ndarray
    weights: np.ndarray | None
    prediction: Prediction
    iterations: int
    converged: bool
    info: dict = field(default_factory=dict)


def _S(lights, k):
    S = np.asarray(getattr(lights, "S", lights), dtype=np.float64)
    if S.shape != (k, 3):
        raise PsbenchError(f"lights must be a Layout or a ({k}, 3) array for {k} images, "
                           f"got shape {S.shape}")
    return S


def _down(a, f, omask_f):
    """Mask-weighted block mean of (H, W[, c]) by the integer factor f."""
    if f == 1:
        return a
    H, W = omask_f.shape
    h, w = -(-H // f), -(-W // f)
    pad = ((0, h * f - H), (0, w * f - W)) + ((0, 0),) * (a.ndim - 2)
    m = np.pad(omask_f, pad[:2])
    x = np.pad(a, pad) * (m if a.ndim == 2 else m[..., None])
    s = x.reshape(h, f, w, f, *a.shape[2:]).sum(axis=(1, 3))
    c = m.reshape(h, f, w, f).sum(axis=(1, 3))
    c = np.maximum(c, 1e-12)
    return (s / (c if a.ndim == 2 else c[..., None])).astype(np.float32)


def _coarse_mask(omask, f):
    if f == 1:
        return omask
    H, W = omask.shape
    h, w = -(-H // f), -(-W // f)
    m = np.pad(omask.astype(np.float32), ((0, h * f - H), (0, w * f - W)))
    return m.reshape(h, f, w, f).mean(axis=(1, 3)) >= 0.5


def predict(b, lights, *, object_mask=None, images=None, valid=None, height=None,
            source="model", bounces=1, samples=24, size=128, sh_bias=0.5):
    """Predict the secondary light of every observation from the current solution.

    Parameters
    ----------
    b : (H, W, 3) float
        Current albedo-scaled normals rho n.
    lights : Layout or (k, 3)
        Illumination vectors (``Layout.S`` = power x direction); distant lights.
    object_mask : (H, W) bool, optional
    images : (k, H, W) float32, optional
        Observations: needed for ``fraction`` and for ``source="images"``.
    valid : (k, H, W) bool, optional
        Observations trusted as emitters with ``source="images"``.
    height : (H, W), optional
        Heights in pixel units; default: integrated from ``b`` (Poisson).
    source : {"model", "images"}
        Emitters: predicted direct Lambert light, or the observed images.
    bounces : {1, 2}
    samples : int
        Azimuths of the ray-casting quadrature (see :mod:`psbench._interreflect`).
    size : int or None
        Largest side of the prediction grid (block means); None: full resolution.
    sh_bias : float
        Shadow-map bias for the predicted cast shadows on integrated heights.

    Returns
    -------
    Prediction
    """
    b = np.asarray(b, dtype=np.float32)
    H, W = b.shape[:2]
    omask = as_mask(object_mask, (H, W), "object_mask")
    if source not in SOURCES:
        raise PsbenchError(f"source={source!r} is not known; valid choices: {', '.join(SOURCES)}")
    if images is None and source == "images":
        raise PsbenchError("source='images' needs images")
    k = _S(lights, len(images) if images is not None else np.shape(getattr(lights, "S", lights))[0]).shape[0]
    S = _S(lights, k)
    normals, albedo = kernel.split(b)
    f = 1 if size is None else max(1, math.ceil(max(H, W) / int(size)))
    mc = _coarse_mask(omask, f)
    bc = _down(b, f, omask.astype(np.float32))
    nc, rc = kernel.split(bc)
    nc[~mc] = (0.0, 0.0, 1.0)
    rc[~mc] = 0.0
    if height is None:
        from .integrate import integrate
        hc = integrate(nc, mc, method="poisson")
        full_h = None
    else:
        full_h = np.asarray(height, dtype=np.float32)
        hc = _down(full_h, f, omask.astype(np.float32)) / np.float32(f)
    hc = np.where(mc, hc, np.float32(hc[mc].min() if mc.any() else 0.0)).astype(np.float32)
    dirs = S / np.maximum(np.linalg.norm(S, axis=1, keepdims=True), 1e-12)
    shade = np.einsum("kc,hwc->khw", S.astype(np.float32), bc * mc[..., None])
    lit = (shade > 0) & ~shadow_map(hc, dirs, mask=mc, bias=sh_bias)
    emit = np.where(lit, shade, np.float32(0.0)).astype(np.float32)
    if source == "images":
        obs = np.asarray(images, np.float32)
        keep = np.ones_like(obs, bool) if valid is None else np.asarray(valid, bool)
        om = omask.astype(np.float32)
        obs_c = np.stack([_down(np.where(keep[i], obs[i], 0.0).astype(np.float32), f, om)
                          for i in range(k)])
        w_c = np.stack([_down(keep[i].astype(np.float32), f, om) for i in range(k)])
        emit = w_c * obs_c + (1.0 - w_c) * emit
        emit *= mc[None]
    irr = secondary(hc, nc, emit, object_mask=mc, rho_d=1.0, bounces=1, samples=samples)
    if bounces == 2:  # light of the first bounce, re-emitted diffusely
        irr += secondary(hc, nc, irr * rc[None], object_mask=mc, rho_d=1.0, bounces=1,
                         samples=samples)
    elif bounces != 1:
        raise PsbenchError(f"bounces must be 1 or 2, got {bounces!r}")
    if f > 1:
        up = cv2.resize(np.ascontiguousarray(np.moveaxis(irr, 0, -1)), None, fx=f, fy=f,
                        interpolation=cv2.INTER_LINEAR)
        if up.ndim == 2:
            up = up[..., None]
        irr = np.ascontiguousarray(np.moveaxis(up[:H, :W], -1, 0))
    sec = irr * (albedo * omask)[None]
    frac = None
    if images is not None:
        obs = np.asarray(images, np.float32)
        frac = np.ones_like(sec)
        np.divide(sec, obs, out=frac, where=obs > 0)
        frac[(obs <= 0) & (sec <= 0)] = 0.0
        np.clip(frac, 0.0, 1.0, out=frac)
    if full_h is None:
        full_h = cv2.resize(hc * np.float32(f), (W, H), interpolation=cv2.INTER_LINEAR) \
            if f > 1 else hc
    return Prediction(sec.astype(np.float32), frac, np.asarray(full_h, np.float32))


def sr_valid(prediction, *, t_sr=0.5):
    """SR validity: True where the predicted secondary fraction is at most ``t_sr``."""
    if prediction.fraction is None:
        raise PsbenchError("the prediction holds no fraction: pass images to predict()")
    return prediction.fraction <= np.float32(t_sr)


def sr_weights(prediction, *, t_sr=0.5):
    """SR weights: ``(1 - f)^2`` where f <= ``t_sr``, else 0; (k, H, W) float32."""
    w = 1.0 - prediction.fraction
    np.square(w, out=w)
    w[~sr_valid(prediction, t_sr=t_sr)] = 0.0
    return w.astype(np.float32)


def _complete(valid, images, S):
    """Eq. 3.1's completion to three observations, with the unmasked least-squares
    residuals computed only at the pixels that need it."""
    short = valid.sum(axis=0) < 3
    if not short.any():
        return valid
    sub = images[:, short][:, :, None]  # (k, n, 1)
    r = kernel.residuals(sub, kernel.ls(sub, S), S)
    out = valid.copy()
    out[:, short] = kernel.complete_three(valid[:, short][:, :, None], r)[:, :, 0]
    return out


def _angle_mean(n1, n2, omask):
    c = np.clip(np.einsum("hwc,hwc->hw", n1, n2)[omask], -1.0, 1.0)
    return float(np.degrees(np.arccos(c)).mean()) if c.size else 0.0


def solve_sr(images, lights, *, object_mask=None, valid=None, mask=None, t_sr=0.5,
             correct=True, weighted=False, max_iter=10, tol=0.02, source="model", bounces=1,
             samples=24, size=128, sh_bias=0.5, damp=0.5, truth_normals=None):
    """Photometric stereo with the SR mask, iterated (a prototype of the mask engine's
    PS <-> normal-mask loop).

    Parameters
    ----------
    images : (k, H, W) float32
    lights : Layout or (k, 3)
    object_mask : (H, W) bool, optional
    valid : (k, H, W) bool, optional
        Observations the rest of the mask expression allows (ANDed every round).
    mask : str, optional
        A mask expression of :func:`psbench.solve` re-evaluated every round on the
        corrected images (``"Th-Hi-Re-Sh"`` gives Th-Hi-Re-Sh-SR); its ``valid`` is
        ANDed with SR's. None: SR alone.
    t_sr : float in (0, 1]
        Mask observations whose predicted secondary fraction exceeds it.
    correct : bool
        Subtract the predicted secondary light (False: the thesis's mask only).
    weighted : bool
        Weighted form: WLS with :func:`sr_weights` instead of the binary mask.
    max_iter : int
        SR rounds (each: predict, mask, re-solve).
    tol : float
        Stop when the mean normal change of a round is below ``tol`` degrees.
    damp : float in [0, 1)
        From the second round on the secondary light used is ``(1 - damp) x new +
        damp x previous`` prediction: the fixed-point iteration can oscillate (V-groove,
        1 bounce: mean NE 2.9 deg after 12 rounds undamped, 1.5 deg with 0.5); on the
        cup it costs two rounds and changes nothing (0.30 / 0.29 deg).
    source, bounces, samples, size, sh_bias
        See :func:`predict`. While the normals still move by more than 1 degree a
        round (the first rounds) the prediction uses half the azimuths: its error is
        then far below that of the normals it starts from.
    truth_normals : (H, W, 3), optional
        Diagnostics: mean NE per round in ``info["ne"]``.

    Returns
    -------
    SRFit

    Notes
    -----
    With ``mask`` the expression judges the *corrected* images, from the first
    round on: on raw images interreflection lifts shadowed observations above Th's
    lower bound (they are lit by other points), and starting from the expression's
    solution on the raw images was measured worse (Lambert cup, 2 bounces:
    30.5 deg against 2.1 deg; TS cup, 1 bounce: 25.5 against 7.3).
    """
    import time

    images = as_images(images, "images", min_count=3)
    k, H, W = images.shape
    S = _S(lights, k)
    omask = as_mask(object_mask, (H, W), "object_mask")
    if not (0.0 < float(t_sr) <= 1.0):
        raise PsbenchError(f"t_sr must be in (0, 1], got {t_sr!r}")
    if not (0.0 <= float(damp) < 1.0):
        raise PsbenchError(f"damp must be in [0, 1), got {damp!r}")
    if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)) or max_iter < 1:
        raise PsbenchError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    base = np.ones((k, H, W), bool) if valid is None else np.asarray(valid, bool)
    if base.shape != (k, H, W):
        raise PsbenchError(f"valid must have shape {(k, H, W)}, got {base.shape}")
    tm = {"predict": 0.0, "solve": 0.0, "mask": 0.0}
    t0 = time.perf_counter()
    b = kernel.wls(images, S, _complete(base, images, S))
    if mask is not None:  # evaluated on the corrected images, from round 1 on (see Notes)
        from .solve import solve as ps_solve
    n_prev = kernel.split(b)[0]
    info = {"change": [], "ne": []}
    if truth_normals is not None:
        info["ne"].append(_angle_mean(n_prev, truth_normals, omask))
    tm["solve"] += time.perf_counter() - t0
    converged, it = False, 0
    v, w = base, None
    change = np.inf
    sec_prev, fine = None, False
    for it in range(1, max_iter + 1):
        t = time.perf_counter()
        fine = fine or change <= 1.0  # once fine, stay fine (no flip-flop of the quadrature)
        ns = samples if fine else max(8, samples // 2)
        pred = predict(b, lights, object_mask=omask, images=images, valid=v, source=source,
                       bounces=bounces, samples=ns, size=size, sh_bias=sh_bias)
        tm["predict"] += time.perf_counter() - t
        t = time.perf_counter()
        if sec_prev is not None and damp > 0:  # relaxation against oscillating rounds
            pred.secondary = (1 - damp) * pred.secondary + damp * sec_prev
        sec_prev = pred.secondary
        J = images - pred.secondary if correct else images
        v = base & sr_valid(pred, t_sr=t_sr)
        if mask is not None:
            v &= ps_solve(J, lights, mask=mask, object_mask=omask).valid
        tm["mask"] += time.perf_counter() - t
        t = time.perf_counter()
        v = _complete(v, J, S)
        w = sr_weights(pred, t_sr=t_sr) * v if weighted else None
        if w is not None:
            w[v & (w <= 0)] = 1e-3  # completed observations keep a small weight
        b = kernel.wls(J, S, w if weighted else v)
        n = kernel.split(b)[0]
        tm["solve"] += time.perf_counter() - t
        change = _angle_mean(n, n_prev, omask)
        info["change"].append(change)
        if truth_normals is not None:
            info["ne"].append(_angle_mean(n, truth_normals, omask))
        n_prev = n
        if change < tol:
            converged = True
            break
    normals, albedo = kernel.split(b)
    normals[~omask] = (0.0, 0.0, 1.0)
    albedo[~omask] = 0.0
    info["timings"] = dict(tm, total=time.perf_counter() - t0)
    return SRFit(b, normals, albedo, v, w, pred, it, converged, info)
