"""Comparison numbers for tsfit: the thesis's masks beside tsfit per noise level.

:func:`noise_comparison` is what an experiment (``robust``, Table 5.3) needs to put
tsfit beside the masks: one row per (noise, method) with the mean normal error and
the time, plus the best mask and its ratio to tsfit per noise level.
:func:`cramer_rao_error` is the floor of any per-pixel estimator on a rendered
scene: how close tsfit is to it, and what no per-pixel fit can beat.
"""
from __future__ import annotations

import time

import numpy as np

__all__ = ["problem", "noise_comparison", "cramer_rao_error", "MASKS"]

#: thesis masks compared by default: plain least squares, Table 5.3's best overall
#: (Th-Hi-Re-Sh) and best single mask (Th), and the Table 5.3 masks that were the
#: best of all 19 on some 16-light TS scene at 5 % noise (semisphere_disc: xNL-Re-Sh,
#: Th-Re-Sh, Hi-Re-Sh; sombrero2: Re)
MASKS = ("None", "Th", "Re", "Hi-Re-Sh", "Th-Re-Sh", "xNL-Re-Sh", "Th-Hi-Re-Sh")


def problem(images, lights, object_mask, mask="None", *, seed=0, truth=None):
    """A :class:`~psbench.solve.base.Problem` whose validity is the mask expression's.

    ``mask`` runs through :func:`psbench.solve` (its ``valid``, after Eq. 3.1's
    completion); the start is that masked least-squares solution.
    """
    from psbench.solve import solve
    from psbench.solve.base import Problem
    res = solve(images, lights, mask=mask, object_mask=object_mask)
    valid = np.ones(images.shape, bool) if mask == "None" else res.valid
    b = res.b
    return Problem(images=images, lights=res.lights, valid=valid, object_mask=object_mask,
                   mask=mask, seed=seed, truth_normals=truth, _start=lambda: b)


def _ne(b, truth, object_mask):
    n = b / np.maximum(np.linalg.norm(b, axis=2, keepdims=True), 1e-12)
    e = np.degrees(np.arccos(np.clip((n * truth).sum(-1), -1.0, 1.0)))
    return float(e[object_mask].mean())


def noise_comparison(surface="sombrero2", lights="45x16", noises=(0.0, 0.05, 0.1, 0.2), *,
                     masks=MASKS, size=128, model="ts", shadows=True, seed=0, options=None,
                     tsfit_mask="None"):
    """tsfit and the thesis's masks on the same rendered images, per noise level.

    Parameters
    ----------
    surface, lights : str
        :func:`psbench.make_surface` name and :func:`psbench.layout` spec.
    noises : sequence of float
        Noise levels (fraction of each image's range).
    masks : sequence of str
        Mask expressions solved by :func:`psbench.solve` for comparison.
    size : int
    model : {"ts", "phong", "lambert"}
        Rendering model (``"phong"``: a model mismatch for tsfit).
    shadows : bool or str
        Passed to :func:`psbench.render`.
    seed : int
        Noise seed.
    options : dict, optional
        :class:`TsfitOptions` fields.
    tsfit_mask : str
        Mask expression whose validity tsfit sees.

    Returns
    -------
    list of dict
        One row per (noise, method): ``noise``, ``method`` ("tsfit" or the mask),
        ``ne`` (mean angular error, degrees, over the object), ``seconds``; the tsfit
        row also holds ``best_mask``, ``best_mask_ne``, ``ratio`` (best mask NE /
        tsfit NE), ``crb_ne`` (the mean of :func:`cramer_rao_error`, cast shadows
        left out; NaN without noise or for another model), ``m``, ``rho_s`` and
        ``converged`` (fraction of object pixels).
    """
    from psbench import layout, make_surface, render
    from psbench.solve import solve
    from psbench.solve.methods.tsfit import TsfitOptions, tsfit
    surf = make_surface(surface, size=size)
    lay = layout(lights)
    opt = TsfitOptions(**(options or {}))
    rows = []
    for noise in noises:
        scene = render(surf, lay, model=model, noise=noise, seed=seed, shadows=shadows)
        mask_rows = []
        for mk in masks:
            t = time.perf_counter()
            res = solve(scene.images, lay, mask=mk, object_mask=surf.object_mask)
            dt = time.perf_counter() - t
            mask_rows.append(dict(noise=noise, method=mk, seconds=dt,
                                  ne=_ne(res.b, surf.normals, surf.object_mask)))
        pr = problem(scene.images, lay, surf.object_mask, tsfit_mask, seed=seed)
        t = time.perf_counter()
        fit = tsfit(pr, opt)
        dt = time.perf_counter() - t
        ne = _ne(fit.b, surf.normals, surf.object_mask)
        best = min(mask_rows, key=lambda r: r["ne"])
        crb = float("nan")
        if model == "ts" and noise > 0:
            crb = float(np.nanmean(cramer_rao_error(surf.normals, surf.object_mask, lay,
                                                    scene.sigma, valid=~scene.cast_shadow)))
        rows.append(dict(noise=noise, method="tsfit", seconds=dt, ne=ne, crb_ne=crb,
                         best_mask=best["method"], best_mask_ne=best["ne"],
                         ratio=best["ne"] / ne if ne > 0 else float("inf"),
                         m=float(np.median(fit.info["m"])),
                         rho_s=float(np.median(fit.info["rho_s"])),
                         converged=float(np.mean(fit.converged[surf.object_mask]))))
        rows.extend(mask_rows)
    return rows


def cramer_rao_error(normals, object_mask, lights, sigma, *, rho_d=1.0, rho_s=1.0, m=2.0,
                     valid=None):
    """Expected angular error (degrees) of an efficient unbiased per-pixel estimator.

    The Cramer-Rao bound of the normal for the Torrance-Sparrow model at the true
    parameters, with Gaussian noise of standard deviation ``sigma[i]`` in image i,
    every observation used (self-shadowed ones are predicted 0), rho_d unknown per
    pixel and the lobe (rho_s, m) known: the bound on the two tangent angles is the
    upper-left 2 x 2 block C of the inverse Fisher matrix, and the expected length
    of a N(0, C) tangent error is sqrt(2 l1 / pi) E(1 - l2 / l1) (l1 >= l2 the
    eigenvalues of C, E the complete elliptic integral of the second kind). A
    first-order bound: it ignores the kink of the model at the self-shadow
    terminator and is not attainable where the errors are large.

    Parameters
    ----------
    normals : (H, W, 3) true unit normals
    object_mask : (H, W) bool
    lights : Layout
    sigma : (k,) noise standard deviation per image (e.g. ``Scene.sigma``)
    rho_d, rho_s, m : float
        The true albedos and lobe width (as rendered).
    valid : (k, H, W) bool, optional
        Observations that carry information (e.g. ``~Scene.cast_shadow``); default
        all.

    Returns
    -------
    (H, W) float64
        Degrees on the object, NaN elsewhere (and where the bound is undefined).
    """
    from scipy.special import ellipe

    from psbench.solve.methods.tsfit import _lm
    L = _lm.Lights(lights.directions, lights.power)
    obj = np.asarray(object_mask, bool)
    n = np.ascontiguousarray(np.asarray(normals, np.float32)[obj].T)
    P = n.shape[1]
    sig = np.asarray(sigma, np.float64).reshape(-1)
    w = np.repeat((1.0 / np.maximum(sig, 1e-30) ** 2)[:, None], P, 1).astype(np.float32)
    if valid is not None:
        w *= np.asarray(valid, bool)[:, obj]
    full = lambda v: np.full(P, v, dtype=np.float32)  # noqa: E731
    _, A, _, _, _ = _lm.evaluate(L, np.zeros((L.k, P), np.float32), w, n, full(rho_d),
                                 full(rho_s), full(m), jac=True)
    A = np.moveaxis(A.astype(np.float64), -1, 0)  # (P, 3, 3) Fisher information
    out = np.full(P, np.nan)
    det = np.linalg.det(A)
    ok = np.isfinite(det) & (det > 0)
    C = np.linalg.inv(A[ok])[:, :2, :2]
    lam = np.linalg.eigvalsh(C)  # ascending
    l1, l2 = np.maximum(lam[:, 1], 1e-300), np.maximum(lam[:, 0], 0.0)
    out[ok] = np.degrees(np.sqrt(2.0 * l1 / np.pi) * ellipe(1.0 - l2 / l1))
    res = np.full(obj.shape, np.nan)
    res[obj] = out
    return res
