"""Comparison numbers for tsfit: the thesis's masks beside tsfit per noise level.

:func:`noise_comparison` is what an experiment (``robust``, Table 5.3) needs to put
tsfit beside the masks: one row per (noise, method) with the mean normal error and
the time, plus the best mask and its ratio to tsfit per noise level.
"""
from __future__ import annotations

import time

import numpy as np

__all__ = ["problem", "noise_comparison", "MASKS"]

#: thesis masks compared by default (Table 5.3's strongest, and plain least squares)
MASKS = ("None", "Th", "Hi-Re-Sh", "Th-Hi-Re-Sh")


def problem(images, lights, object_mask, mask="None", *, seed=0, truth=None):
    """A :class:`~psbench.solve.base.Problem` whose validity is the mask expression's.

    ``mask`` runs through :func:`psbench.solve` (its ``valid``, after Eq. 3.1's
    completion); the start is that masked least-squares solution.
    """
    from ...solve import solve
    from ..base import Problem
    res = solve(images, lights, mask=mask, object_mask=object_mask)
    valid = np.ones(images.shape, bool) if mask == "None" else res.valid
    b = res.b
    return Problem(images=images, lights=res.lights, valid=valid, object_mask=object_mask,
                   mask=mask, seed=seed, truth_normals=truth, _start=lambda: b)


def _ne(b, truth, mask):
    n = b / np.maximum(np.linalg.norm(b, axis=2, keepdims=True), 1e-12)
    e = np.degrees(np.arccos(np.clip((n * truth).sum(-1), -1.0, 1.0)))
    return float(e[mask].mean())


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
        tsfit NE), ``m``, ``rho_s`` and ``converged`` (fraction of object pixels).
    """
    from ... import layout, make_surface, render
    from ...solve import solve
    from .tsfit import TsfitOptions, tsfit
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
        rows.append(dict(noise=noise, method="tsfit", seconds=dt, ne=ne,
                         best_mask=best["method"], best_mask_ne=best["ne"],
                         ratio=best["ne"] / ne if ne > 0 else float("inf"),
                         m=float(np.median(fit.info["m"])),
                         rho_s=float(np.median(fit.info["rho_s"])),
                         converged=float(np.mean(fit.converged[surf.object_mask]))))
        rows.extend(mask_rows)
    return rows
