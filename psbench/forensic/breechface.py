"""The real breech-face study: do PS reconstructions of real marks identify the gun?

Each real scan (X3P heights in µm, :func:`psbench.forensic.scans.read_guns`) is rendered
through the rig simulator (:func:`psbench.forensic.acquire`: a finish preset, the scan's
own pixel size, the Chapter 7 acquisition, seeded camera noise), reconstructed by every
method and integrator of :mod:`psbench.forensic.pipeline`, band-passed, and every pair
of scans is compared by congruent matching cells (:func:`psbench.forensic.cmc`: the CMC
count and CCFmax). The scans themselves (:data:`SCAN`) are the upper bound.

:func:`reconstruct_scan` is the per-scan work (cached by the caller: pairs then cost
only the comparison); :func:`score_pairs` the per-pair work; :func:`summarise` the
per-method table: AUC (of the CMC count and of CCFmax), separation (smallest same-gun
score minus largest different-gun score), false positives / negatives at the CMC
decision threshold (:data:`~psbench.forensic.cmc.CMC_THRESHOLD`), equal error rate,
height error against the scan (µm, band-passed) and time.
"""
from __future__ import annotations

import time

import numpy as np
import pandas as pd

from ..integrate.bilateral import bilateral_integrate  # noqa: F401  (INTEGRATORS uses it)
from .._shared.checks import PsbenchError
from .._shared.checks import workers as check_workers
from ..solve import solve
from ..surfaces import surface_from_height
from ._cmc_search import SEARCH_REVISION
from .cmc import CMC_DEFAULTS, CMC_THRESHOLD, cmc
from .identify import bandpass
from .pipeline import INTEGRATORS, auc, solve_kwargs, warm_up_integrators
from .presets import ACQUISITION, acquire

__all__ = ["SCAN", "STUDY_METHODS", "render_scan", "reconstruct_scan", "score_pairs",
           "equal_error_rate", "summarise"]

#: method label of the scans themselves (the identification's upper bound)
SCAN = "scan"
#: the study's PS methods (labels of :data:`psbench.forensic.pipeline.RECIPES`)
STUDY_METHODS = ("None", "Th-Hi-Re-Sh", "weighted Th-Hi-Re-Sh", "WPS", "robust", "tsfit")


def render_scan(height_um, valid, *, pixel_size, finish="brass", seed=0, meter="object"):
    """Acquire a scan with the rig simulator: heights (µm) to pixel units at the scan's
    own pixel size; missing data filled with 0 (outside ``valid``, which is the object).

    ``meter``: where the exposure's mean level (75/255, the Chapter 7 rule) is measured.
    ``"object"`` (default): on the scan's valid region, as an examiner meters on the
    case; ``"frame"``: on the whole frame, :func:`~psbench.forensic.acquire`'s rule,
    which on a scan whose data covers a third of the frame (the rest renders black)
    exposes the face about three times brighter and clips most of the 31° ring.

    Returns
    -------
    Acquisition
    """
    valid = np.asarray(valid, bool)
    z = np.where(valid, np.asarray(height_um, np.float64), 0.0) / float(pixel_size)
    surf = surface_from_height(z, object_mask=valid, name="scan")
    level = ACQUISITION["mean_level"]
    if meter == "object":        # the background renders 0: the frame mean is diluted
        level *= float(valid.mean())
    elif meter != "frame":
        raise PsbenchError(f"meter={meter!r} is not known; valid choices: object, frame")
    return acquire(surf, finish=finish, seed=seed, mean_level=level)


def reconstruct_scan(height_um, valid, *, pixel_size, methods=STUDY_METHODS,
                     integrators=tuple(INTEGRATORS), finish="brass", seed=0,
                     short=CMC_DEFAULTS["short"], long=CMC_DEFAULTS["long"],
                     recipe=None, meter="object"):
    """Render one scan, reconstruct it with every method and integrator, band-pass.

    Parameters
    ----------
    height_um : (H, W) float
        Scan heights, µm (NaN where missing).
    valid : (H, W) bool
    pixel_size : float
        µm per pixel.
    methods, integrators : sequences of labels
    finish : str
        Preset of :data:`~psbench.forensic.FINISH_PRESETS`.
    seed : int
        Camera-noise seed.
    short, long : float
        Band-pass (µm) applied to every reconstruction and to the scan.
    meter : {"object", "frame"}
        Exposure metering of :func:`render_scan`.
    recipe : callable or dict, optional
        ``recipe(images, lights, object_mask=, pixel_size=) -> heights (µm)``, scored as
        method ``"recipe"`` (integrator ``"-"``); a dict ``{integrator: recipe}`` scores
        each under its integrator.

    Returns
    -------
    maps : dict
        (method, integrator) -> band-passed heights (float32, µm); the scan under
        (:data:`SCAN`, "-").
    rows : list of dict
        ``method, integrator, height_error_um`` (mean |difference| of the band-passed
        maps over ``valid``), ``solve_s``, ``integrate_s``.
    """
    valid = np.asarray(valid, bool) & np.isfinite(height_um)
    bp = lambda h: bandpass(h, valid, pixel_size=pixel_size, short=short, long=long)  # noqa: E731
    ref = bp(np.where(valid, height_um, 0.0))
    maps = {(SCAN, "-"): ref}
    rows = []
    acq = render_scan(height_um, valid, pixel_size=pixel_size, finish=finish, seed=seed,
                      meter=meter)

    def keep(method, integ, h, t_solve, t_int):
        f = bp(h)
        maps[(method, integ)] = f
        rows.append({"method": method, "integrator": integ,
                     "height_error_um": float(np.abs(f - ref)[valid].mean()),
                     "solve_s": t_solve, "integrate_s": t_int})

    warm_up_integrators(integrators)
    for name in methods:
        t0 = time.perf_counter()
        res = solve(acq.images, acq.lights, object_mask=valid,
                    **solve_kwargs(name, pixel_size))
        t_solve = time.perf_counter() - t0
        for integ in integrators:
            t0 = time.perf_counter()
            h = INTEGRATORS[integ](res.normals, valid) * np.float32(pixel_size)
            keep(name, integ, h, t_solve, time.perf_counter() - t0)
        del res
    recipes = recipe if isinstance(recipe, dict) else {"-": recipe} if recipe else {}
    for integ, rec in recipes.items():
        t0 = time.perf_counter()
        h = rec(acq.images, acq.lights, object_mask=valid, pixel_size=pixel_size)
        keep("recipe", integ, h, time.perf_counter() - t0, 0.0)
    return maps, rows


def _compare(targets, za, va, maps, valid, pixel_size, options):
    """CMC rows of one reference (``za``, ``va``) against ``targets`` (names); outputs of
    :func:`cmc` only."""
    out = []
    for b in targets:
        t0 = time.perf_counter()
        r = cmc(za, maps[b], va, valid[b], pixel_size=pixel_size, filtered=True, workers=1,
                **options)
        out.append({"count": r.count, "cells": len(r.cells), "ccf": r.ccf, "dx": r.pose.dx,
                    "dy": r.pose.dy, "theta": r.pose.theta,
                    "seconds": time.perf_counter() - t0})
    return out


def score_pairs(maps, valid, guns, *, pixel_size, cache=None, jobs=1, progress=None,
                **cmc_options):
    """CMC count and CCFmax of every pair of scans for one (method, integrator).

    Parameters
    ----------
    maps : dict
        scan -> band-passed heights (µm).
    valid : dict
        scan -> valid mask.
    guns : dict
        scan -> gun.
    pixel_size : float
        µm per pixel of every map.
    cache : StudyCache or path, optional
        Keep each reference scan's comparisons (:class:`~.study_cache.StudyCache`):
        a stopped study resumes, and maps met before are not compared again.
    jobs : int, default 1
        Worker processes (joblib; -1: one per core): the references are shared out.
    progress : callable, optional
        ``progress(done, total)`` after each reference scan (pairs done, pairs).
    **cmc_options
        Options of :func:`~psbench.forensic.cmc` (``filtered=True`` is implied; each
        comparison runs on one thread: ``jobs`` is the parallelism).

    Returns
    -------
    DataFrame
        ``a, b, same_gun, count, cells, ccf, dx, dy, theta, seconds`` (seconds: the
        comparison's wall time when it was computed, also if it came from the cache).
    """
    from .study_cache import StudyCache, digest

    check_workers(jobs, "jobs")
    cache = cache if isinstance(cache, StudyCache) else StudyCache(cache)
    names = sorted(maps)
    keys = {n: digest(maps[n], valid[n], float(pixel_size)) for n in names}
    # the search's revision too: a cache written by another search is not read
    options = {**cmc_options, "pixel_size": float(pixel_size), "filtered": True,
               "search": SEARCH_REVISION}

    def one(i):
        a, targets = names[i], names[i + 1:]
        by_key = dict(zip((keys[b] for b in targets), targets))

        def compute(missing):
            return _compare([by_key[k] for k in missing], maps[a], valid[a], maps, valid,
                            pixel_size, cmc_options)
        return cache.pairs(options, keys[a], [keys[b] for b in targets], compute)

    total = len(names) * (len(names) - 1) // 2
    if jobs == 1:
        done_refs = ((i, one(i)) for i in range(len(names) - 1))
    else:
        from joblib import Parallel, delayed

        done_refs = Parallel(n_jobs=jobs, return_as="generator_unordered")(
            delayed(_indexed)(one, i) for i in range(len(names) - 1))
    got, done = {}, 0
    for i, res in done_refs:
        got[i] = res
        done += len(res)
        if progress:
            progress(done, total)
    results = [got[i] for i in range(len(names) - 1)]
    rows = []
    for i, res in enumerate(results):
        a = names[i]
        for b, r in zip(names[i + 1:], res):
            rows.append({"a": a, "b": b, "same_gun": guns[a] == guns[b], **r})
    return pd.DataFrame(rows, columns=["a", "b", "same_gun", "count", "cells", "ccf", "dx",
                                       "dy", "theta", "seconds"])


def _indexed(fn, i):
    return i, fn(i)


def equal_error_rate(positive, negative):
    """Equal error rate of a score (higher = same source): the rate where the false
    positive and false negative rates of a threshold cross (mean of the two there)."""
    p = np.sort(np.asarray(positive, float)[np.isfinite(positive)])
    q = np.sort(np.asarray(negative, float)[np.isfinite(negative)])
    if not len(p) or not len(q):
        return float("nan")
    ts = np.unique(np.concatenate([p, q, [np.inf]]))
    fnr = np.searchsorted(p, ts, side="left") / len(p)          # positives below t
    fpr = 1.0 - np.searchsorted(q, ts, side="left") / len(q)    # negatives >= t
    i = int(np.argmin(np.abs(fnr - fpr)))
    return float(0.5 * (fnr[i] + fpr[i]))


def summarise(scores, per_scan=None, by=("finish", "method", "integrator"),
              threshold=CMC_THRESHOLD):
    """Per group: AUC, separation, FP/FN at the CMC threshold, EER, height error, time.

    ``scores`` are :func:`score_pairs` rows with the ``by`` columns; ``per_scan`` the
    :func:`reconstruct_scan` rows with the same columns (means of height error, solve
    and integration time are joined).
    """
    out = []
    for key, g in scores.groupby(list(by), sort=False):
        s, d = g[g.same_gun], g[~g.same_gun]
        out.append({**dict(zip(by, key)),
                    "auc_cmc": auc(s["count"], d["count"]), "auc_ccf": auc(s.ccf, d.ccf),
                    "separation_cmc": float(s["count"].min() - d["count"].max()),
                    "separation_ccf": float(s.ccf.min() - d.ccf.max()),
                    "fp": int((d["count"] >= threshold).sum()),
                    "fn": int((s["count"] < threshold).sum()),
                    "eer_cmc": equal_error_rate(s["count"], d["count"]),
                    "eer_ccf": equal_error_rate(s.ccf, d.ccf),
                    "same_median_cmc": float(s["count"].median()),
                    "diff_max_cmc": float(d["count"].max()),
                    "n_same": len(s), "n_diff": len(d), "pair_s": float(g.seconds.median())})
    table = pd.DataFrame(out)
    if per_scan is not None and len(per_scan):
        means = per_scan.groupby(list(by), sort=False)[
            ["height_error_um", "solve_s", "integrate_s"]].mean().reset_index()
        table = table.merge(means, on=list(by), how="left")
    return table
