"""The real breech-face study as runs of the benchmark harness (experiment ``breechface``).

``psbench +experiment=breechface`` runs :func:`run` through
:func:`psbench.analysis.breechface` (``kind=analysis``) and stores its json payload, one
row per run. The scans are the X3P files of ``study["folder"]`` with their
``guns.csv`` (:func:`~.scans.read_guns`; ``$PSBENCH_X3P``, default
``../shared/data/forensic/weller``), optionally ``per_gun`` scans of each of ``guns``.
A run is one ``part``:

``method``
    One method label (:data:`~.breechface.STUDY_METHODS`, or ``"recipe"``: psbench's
    :func:`~.recipe.reconstruct_heights`) on every scan, for one finish and integrator
    (``finish``, ``integrator``) or for all of the study's: each scan rendered
    by the rig simulator (:func:`~.breechface.render_scan`: the finish preset, the
    scan's own pixel size, the Chapter 7 acquisition, camera-noise seed = the run's
    ``seed``), solved, integrated by every integrator, band-passed; then every pair of
    scans compared (:func:`~.cmc.cmc`: CMC count and CCFmax). Per scan: height error
    against the scan (µm) and the stage times; per pair: the scores and their time.
``scan``
    The scans themselves compared (the identification's upper bound).
``panels``
    One same-gun pair (the first two scans of the first gun): scan, one rendered image
    and the recipe's reconstruction of the second, and the CMC cells of the pair drawn
    on both, for scans and for reconstructions (PNG pictures, base64).

All scans are compared at one pixel size: scans of other pixel sizes are resampled to
the coarsest (:func:`~.scans.resample`, with a warning). ``crop`` keeps the
``crop`` x ``crop`` pixels of each scan where the scans hold the most data (the ``ci``
scale: fewer pixels, the same pixel size and band-pass). The CMC
translation tolerance is cmcR's 20 px at its 6.25 µm working resolution, i.e.
``translation_tol_um`` = 125 µm, converted to pixels; the other CMC parameters are
:data:`~.cmc.CMC_DEFAULTS`.

Long studies: ``study["cache"]`` (a folder; the full scale's is
``$PSBENCH_CACHE/breechface``) keeps every finished scan map and every reference scan's
comparisons (:mod:`~.study_cache`), so a stopped run resumes; ``study["pairs_table"]``
(a Parquet table; the full scale's is the committed
``reports/data/breechface_pairs.parquet``) holds the comparisons of earlier checkouts,
keyed by the digests of the maps compared: a run reads the pairs whose maps are
bit-identical to the table's instead of comparing them again, and adds its own to it
when it ends; ``study["jobs"]`` shares
the comparisons of one run among worker processes (default 1: the harness already runs
one run per core). Progress (scans reconstructed, pairs compared, minutes left) goes to
stderr.
"""
from __future__ import annotations

import base64
import os
import time
import warnings

import numpy as np

from .._shared.checks import PsbenchError
from .._shared.checks import workers as check_workers
from . import breechface as bf
from .cmc import CMC_DEFAULTS
from .identify import bandpass
from .presets import FINISH_PRESETS
from .study_cache import StudyCache

__all__ = ["STUDY", "PARTS", "LABELS", "RECIPE", "run", "load_scans", "method_maps",
           "study_options", "run_scores"]

#: method label of psbench's recipe (:func:`psbench.forensic.reconstruct_heights`)
RECIPE = "recipe"
#: the method labels of ``part="method"`` runs
LABELS = tuple(bf.STUDY_METHODS) + (RECIPE,)
PARTS = ("method", "scan", "panels")
#: defaults of the ``study`` run parameter
STUDY = {"folder": None, "guns": None, "per_gun": None, "crop": None,
         "finishes": ["brass", "nickel"], "integrators": ["poisson", "bilateral"],
         "meter": "frame", "translation_tol_um": 125.0, "methods": None, "cache": None,
         "pairs_table": None, "jobs": 1}


def study_options(study):
    """:data:`STUDY` updated by ``study`` (a dict of overrides), checked: unknown keys,
    finishes, methods, integrators, ``jobs``, ``cache`` and ``pairs_table`` get one-line
    errors."""
    st = dict(STUDY)
    extra = set(study or {}) - set(st)
    if extra:
        raise PsbenchError(f"study has unknown keys {sorted(extra)}; valid: {', '.join(st)}")
    st.update(study or {})
    for f in st["finishes"]:
        if f not in FINISH_PRESETS:
            raise PsbenchError(f"study finishes: {f!r} is not a finish preset; valid: "
                               f"{', '.join(FINISH_PRESETS)}")
    for m in st["methods"] or ():
        if m not in LABELS:
            raise PsbenchError(f"study methods: {m!r} is not known; valid: {', '.join(LABELS)}")
    check_workers(st["jobs"], "study jobs")
    for key, what in (("cache", "a folder path"), ("pairs_table", "a Parquet file path")):
        if st[key] is not None and not isinstance(st[key], (str, os.PathLike)):
            raise PsbenchError(f"study {key}: must be {what} or null, got {st[key]!r}")
    for i in st["integrators"]:
        if i not in ("poisson", "bilateral"):
            raise PsbenchError(f"study integrators: {i!r} is not known; valid: poisson, "
                               "bilateral")
    return st


def load_scans(st):
    """The study's scans: ``(names, heights, valid masks, guns, pixel size)``.

    Heights (µm) NaN where missing; all at one pixel size (the coarsest of the scans),
    resampled with a warning where needed; cropped to ``st["crop"]`` pixels if set.
    """
    from ..io import read_x3p
    from .scans import read_guns, resample

    table = read_guns(st["folder"])
    if st["guns"] is not None:
        want = [str(g) for g in st["guns"]]
        missing = sorted(set(want) - set(table.gun.astype(str)))
        if missing:
            raise PsbenchError(f"study guns {missing} are not in guns.csv of "
                               f"{st['folder'] or 'the scan folder'}")
        table = table[table.gun.astype(str).isin(want)]
    if st["per_gun"] is not None:
        table = table.groupby("gun", sort=False).head(int(st["per_gun"]))
    if len(table) < 2:
        raise PsbenchError("the study needs at least 2 scans")
    topos = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # x3pio's own warnings about the files
        topos = [read_x3p(p) for p in table.path]
    px = max(t.pixel_size for t in topos)
    heights, valid = [], []
    for name, t in zip(table.scan, topos):
        z, v = t.height, t.valid & np.isfinite(t.height)
        if abs(t.pixel_size - px) > 1e-6 * px:
            warnings.warn(f"scan {name}: {t.pixel_size:g} um pixels resampled to the "
                          f"study's {px:g} um", stacklevel=3)
            z, v = resample(z, v, pixel_size=t.pixel_size, to=px)
        heights.append(np.where(v, z, np.nan).astype(np.float32))
        valid.append(v)
    if st["crop"]:
        heights, valid = _crop(heights, valid, int(st["crop"]))
    return list(table.scan), heights, valid, list(table.gun.astype(str)), float(px)


def _crop(heights, valid, c):
    """The c x c window (one place for every scan) holding the most data of all scans."""
    H, W = min(v.shape[0] for v in valid), min(v.shape[1] for v in valid)
    c = min(c, H, W)
    total = sum(v[:H, :W].astype(np.int32) for v in valid)
    ii = np.pad(total.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    box = ii[c:, c:] - ii[:-c, c:] - ii[c:, :-c] + ii[:-c, :-c]
    r, k = np.unravel_index(int(np.argmax(box)), box.shape)
    return ([h[r:r + c, k:k + c] for h in heights], [v[r:r + c, k:k + c] for v in valid])


def _recipe(integrator):
    from .recipe import reconstruct_heights

    def rec(images, lights, *, object_mask, pixel_size):
        return reconstruct_heights(images, lights, object_mask=object_mask,
                                   pixel_size=pixel_size, integrator=integrator)
    return rec


def _cmc_options(st, px):
    return {"translation_tol": float(st["translation_tol_um"]) / px}


def run_scores(maps, valid, guns, px, st, cache=None, **head):
    """Every pair of ``maps`` compared as the study compares them (its CMC options,
    ``jobs`` and cache), with progress on stderr; records with ``head``'s fields first."""
    tag = "/".join(str(v) for v in head.values())
    seen = [(time.perf_counter(), 0)]

    def progress(done, total):
        now = time.perf_counter()
        seen.append((now, done))
        if done == total or now - progress.last > 30:
            progress.last = now
            # the rate of the last references: cached ones come back at once
            t0, d0 = seen[max(0, len(seen) - 11)]
            left = (total - done) * (now - t0) / max(done - d0, 1)
            _say(f"{tag}: {done} of {total} pairs compared (about {left / 60:.0f} min left)")
    progress.last = seen[0][0]
    sc = bf.score_pairs(maps, valid, guns, pixel_size=px, cache=cache, jobs=st["jobs"],
                        progress=progress, **_cmc_options(st, px))
    for k, v in head.items():
        sc.insert(0, k, v)
    return sc.to_dict("records")


def run(part="method", label=None, *, finish=None, integrator=None, seed=0, study=None):
    """One run of the breechface study (see the module docstring).

    Parameters
    ----------
    part : {"method", "scan", "panels"}
    label : str
        Method label of a ``method`` run (:data:`LABELS`).
    finish, integrator : str, optional
        A ``method`` run of this finish preset / integrator only (default: every one of
        the study's ``finishes`` / ``integrators``). One that the study does not list
        returns ``{"skipped": True}`` at once, as a label outside ``methods`` does:
        the full scale's grid has one run per label, finish and integrator (about half
        an hour each on the 95 shared scans), so that a partly run study is a partly
        filled grid.
    seed : int
        Camera-noise seed of every rendering.
    study : dict, optional
        Overrides of :data:`STUDY`: ``folder`` (of the X3P scans and guns.csv),
        ``guns`` and ``per_gun`` (a subset), ``crop`` (pixels: the square window holding
        the most data), ``finishes``, ``integrators``, ``meter`` (exposure metering of
        :func:`~.breechface.render_scan`), ``translation_tol_um``, ``methods`` (the
        labels this scale runs; a ``method`` run of another label returns
        ``{"skipped": True}`` at once), ``cache`` (folder of the study cache, or None),
        ``pairs_table`` (Parquet table of earlier comparisons, read and extended; or
        None)
        and ``jobs`` (worker processes for the comparisons; -1: one per core).

    Returns
    -------
    dict
        json-able payload; tables are lists of records.
    """
    if part not in PARTS:
        raise PsbenchError(f"part={part!r} is not known; valid choices: {', '.join(PARTS)}")
    if part == "method" and label not in LABELS:
        raise PsbenchError(f"part='method' needs label= one of {', '.join(LABELS)}, "
                           f"got {label!r}")
    st = study_options(study)
    for name, v, known, key in (("finish", finish, FINISH_PRESETS, "finishes"),
                                ("integrator", integrator, ("poisson", "bilateral"),
                                 "integrators")):
        if v is None:
            continue
        if part != "method":
            raise PsbenchError(f"{name}= is for part='method' runs only, got part={part!r}")
        if v not in known:
            raise PsbenchError(f"{name}={v!r} is not known; valid: {', '.join(known)}")
        if v not in st[key]:
            return {"part": part, "label": label, "seed": int(seed), "skipped": True}
        st[key] = [v]
    if part == "method" and st["methods"] is not None and label not in st["methods"]:
        return {"part": part, "label": label, "seed": int(seed), "skipped": True}
    names, heights, valid, guns, px = load_scans(st)
    cache = StudyCache(st["cache"], st["pairs_table"])
    gun = dict(zip(names, guns))
    vmask = dict(zip(names, valid))
    head = {"part": part, "label": label, "seed": int(seed), "pixel_size": px,
            "scans": names, "guns": guns}
    if part == "scan":
        maps = {n: bandpass(np.where(v, h, 0.0), v, pixel_size=px,
                            short=CMC_DEFAULTS["short"], long=CMC_DEFAULTS["long"])
                for n, h, v in zip(names, heights, valid)}
        scores = run_scores(maps, vmask, gun, px, st, cache, method=bf.SCAN, integrator="-",
                         finish="-")
        _export(cache)
        return {**head, "scores": scores}
    if part == "panels":
        return {**head, **_panels(names, heights, valid, guns, px, st, seed)}
    per_scan, scores = [], []
    for finish in st["finishes"]:
        maps, rows = method_maps(label, names, heights, valid, px, st, seed=seed,
                                 finish=finish, cache=cache)
        per_scan += rows
        for integ, mm in maps.items():
            scores += run_scores(mm, vmask, gun, px, st, cache, method=label,
                              integrator=integ, finish=finish)
    _export(cache)
    return {**head, "per_scan": per_scan, "scores": scores}


def _export(cache):
    """The run's comparisons into the study's pairs table (when it has one)."""
    if cache.table is not None and cache.root is not None:
        _say(f"{cache.export()} comparisons in the pairs table {cache.table}")


def method_maps(label, names, heights, valid, px, st, *, seed, finish, cache=None):
    """Every scan rendered with ``finish`` and reconstructed by method ``label``.

    Returns ``({integrator: {scan: band-passed map}}, per-scan rows)``; with a
    :class:`~.study_cache.StudyCache` each scan's maps are kept and reused.
    """
    from .study_cache import StudyCache, digest

    cache = cache if isinstance(cache, StudyCache) else StudyCache(cache)
    maps, per_scan = {}, []
    for n, (name, h, v) in enumerate(zip(names, heights, valid)):
        def compute():
            t0 = time.perf_counter()
            if label == RECIPE:
                recipes = {i: _recipe(i) for i in st["integrators"]}
                m, rows = bf.reconstruct_scan(h, v, pixel_size=px, methods=(),
                                              finish=finish, seed=seed, recipe=recipes,
                                              meter=st["meter"])
            else:
                m, rows = bf.reconstruct_scan(h, v, pixel_size=px, methods=(label,),
                                              integrators=tuple(st["integrators"]),
                                              finish=finish, seed=seed, meter=st["meter"])
            total = time.perf_counter() - t0
            rows = [{**r, "finish": finish, "scan": name, "scan_s": total} for r in rows]
            return ([m[(label, i)] for i in st["integrators"]],
                    [[r for r in rows if r["integrator"] == i] for i in st["integrators"]])
        base = digest(h, v, finish, st["meter"], int(seed), label, float(px),
                      CMC_DEFAULTS["short"], CMC_DEFAULTS["long"])
        integs = list(st["integrators"])
        m, rows = cache.maps([f"{base}-{integ}" for integ in integs], compute)
        for integ, z in zip(integs, m):
            maps.setdefault(integ, {})[name] = z
        per_scan += [r for rr in rows for r in rr]
        _say(f"{label} {finish}: {n + 1} of {len(names)} scans reconstructed")
    return maps, per_scan


def _say(msg):
    """Progress of a long study on stderr (one line each)."""
    import sys

    print(f"breechface: {msg}", file=sys.stderr, flush=True)


def _png(img):
    import cv2

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(img[..., ::-1]))
    return base64.b64encode(buf.tobytes()).decode("ascii")


def _panels(names, heights, valid, guns, px, st, seed):
    """Scan, rendered image and recipe reconstruction of one same-gun pair, with cells."""
    from ..io.x3p import Topography
    from ._cmc_picture import _gray, cells_picture
    from .cmc import cmc

    first = guns[0]
    idx = [i for i, g in enumerate(guns) if g == first][:2]
    if len(idx) < 2:
        raise PsbenchError(f"the panels need two scans of gun {first}; the study has one")
    ia, ib = idx
    finish = st["finishes"][0]
    integ = st["integrators"][0]
    topo = lambda n, z, v: Topography(height=np.where(v, z, np.nan).astype(np.float32),  # noqa: E731
                                      valid=v, pixel_size=px, name=n)
    opts = _cmc_options(st, px)
    out = {"pair": [names[ia], names[ib]], "finish": finish, "integrator": integ}
    ta, tb = topo(names[ia], heights[ia], valid[ia]), topo(names[ib], heights[ib], valid[ib])
    r = cmc(ta.height, tb.height, ta.valid, tb.valid, pixel_size=px, **opts)
    out["scan_cells"] = _png(cells_picture(r, ta, tb))
    out["scan_count"], out["scan_ccf"] = int(r.count), float(r.ccf)
    recon = []
    for i in (ia, ib):
        acq = bf.render_scan(heights[i], valid[i], pixel_size=px, finish=finish, seed=seed,
                             meter=st["meter"])
        if i == ib:
            k = int(np.argmin(acq.lights.directions[:, 2]))     # a 62 deg image: no clipping
            img = acq.images[k].astype(np.float32) / float(np.iinfo(acq.images.dtype).max)
            out["image"] = _png(_gray(img, valid[i]))
        recon.append(_recipe(integ)(acq.images, acq.lights, object_mask=valid[i],
                                    pixel_size=px))
    ra, rb = topo(names[ia], recon[0], valid[ia]), topo(names[ib], recon[1], valid[ib])
    r = cmc(ra.height, rb.height, ra.valid, rb.valid, pixel_size=px, **opts)
    out["recipe_cells"] = _png(cells_picture(r, ra, rb))
    out["recipe_count"], out["recipe_ccf"] = int(r.count), float(r.ccf)
    return out
