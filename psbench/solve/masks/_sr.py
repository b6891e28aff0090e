"""SR, the secondary-reflection normal mask (thesis Section 8.3): the prediction.

The mask itself is :mod:`psbench.solve.masks.sr` (``ps.solve(..., mask="SR")``); the
mask engine iterates it (see *Corrections* in :mod:`psbench.solve.base`).

The thesis proposes "a mask working similar to the ray tracing algorithm", iterated
inside unified PS because removing observations changes the normals and so the
traced light. psbench's SR step:

1. from the current solution b = rho n: normals, albedo, and heights integrated
   from the normals (or given);
2. predict the light every observation receives from other surface points by the
   ray casting of :mod:`psbench.render._interreflect` (the same quadrature the renderer
   uses), with the *predicted* direct Lambert images as emitters
   (``source="model"``: ``rho (s.n)`` where s.n > 0 and not cast-shadowed on the
   integrated heights) or the observed images (``source="images"``, Lambertian
   emitters, all bounces at once; observations outside ``valid`` replaced by the
   model); on a grid of at most ``size`` pixels a side (the secondary light is
   smooth), upsampled, times the full-resolution albedo;
3. mask the observations whose predicted secondary fraction ``f = S / I`` exceeds
   ``t_sr`` and -- unless ``sr_correct=False`` -- subtract the predicted secondary
   light from the images (the weighted form, ``weighted=True``, is the engine's
   weighted-mask step on the corrected images);
4. re-solve, repeat until the normals stop moving.

Why the subtraction: on a Lambertian concave surface the one-bounce light of a lit
observation is ``c_i(p) = rho(p) sum_q K(p, q) rho(q) (s_i . n_q)``, linear in s_i,
so a lit observation reads ``s_i . (rho n + sum_q K rho rho_q n_q)``: a *consistent*
pseudo-normal (a spherical cup: exactly ``rho n + kappa z``). Masking alone cannot
see it -- every lit observation agrees on the wrong normal -- and only helps where the
secondary light dominates (shadowed observations, f = 1). The subtraction, the
iteration of Nayar, Ikeuchi and Kanade's "shape from interreflections", removes it.
``sr_correct=False`` is the literal mask of the thesis, kept for comparison.

Limits (measured: the ``interreflection`` experiment, ``benchmarks/bench_interreflect.py``):
the prediction is Lambertian. On Torrance-Sparrow images SR alone is worse than plain
least squares (highlights inflate the albedo it predicts from, and it over-subtracts);
it needs the highlight masks (``mask="Th-Hi-Re-Sh-SR"``). On images without
interreflection it subtracts light that is not there and costs accuracy.
``sr_bounces`` should match the world: a prediction of one bounce leaves the second
uncorrected, and vice versa.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from ..._shared.checks import PsbenchError, as_mask
from ...render._interreflect import secondary
from ...render.shadowmap import shadow_map
from .. import kernel

__all__ = ["predict", "sr_valid", "Prediction", "SOURCES"]

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
        Azimuths of the ray-casting quadrature (see :mod:`psbench.render._interreflect`).
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
        from ...integrate.poisson import integrate
        hc = integrate(nc, object_mask=mc, integrator="poisson")
        full_h = None
    else:
        full_h = np.asarray(height, dtype=np.float32)
        hc = _down(full_h, f, omask.astype(np.float32)) / np.float32(f)
    hc = np.where(mc, hc, np.float32(hc[mc].min() if mc.any() else 0.0)).astype(np.float32)
    dirs = S / np.maximum(np.linalg.norm(S, axis=1, keepdims=True), 1e-12)
    shade = np.einsum("kc,hwc->khw", S.astype(np.float32), bc * mc[..., None])
    lit = (shade > 0) & ~shadow_map(hc, dirs, object_mask=mc, bias=sh_bias)
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
