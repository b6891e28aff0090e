"""Chapter 4 / Section 5.7 analyses as tidy pandas DataFrames (no plotting, no file I/O).

Every function renders synthetic scenes (:func:`psbench.render.render`), solves them
and measures errors; all are seeded and take a ``size`` so tests and CI can run them
small. Plots are made elsewhere from the returned frames.

Image kinds used throughout (the ``kind=`` of the analyses, ``IMAGE_KINDS``; thesis Figs.
4.3, 4.4, 4.7):

* ``"Di"`` (diffuse): ``model="lambert", shadows="none"`` -- images "without highlight
  and shadow" (thesis lines ~824, ~830): plain unclamped Lambert I = rho_d s . n, which
  is negative where s . n < 0, so least squares is exact up to noise (the premise of the
  optimal-lighting analyses of Section 2.4). Not a physical camera image.
* ``"Di-clamped"``: ``model="lambert", shadows="self"`` -- Lambert without cast shadows
  but with attached (self) shadows clamped to 0 (psbench's earlier "Di"); at zeniths
  above 90 - max surface zenith some observations are attached shadows.
* ``"Hi-Sh"``: ``model="ts", shadows=True`` (Torrance-Sparrow highlights, self and cast
  shadows), the thesis's Table 5.1 parameters (rho_d = rho_s = 1, m = 2).

Noise is Gaussian with sigma = ``noise`` x each image's dynamic range (5 % default).
"""
from __future__ import annotations

import numpy as np

from ._common import IMAGE_KINDS  # noqa: F401  (public here)
from ._common import _edges, _ne, _ps, _render, _ring, _seq, _sname, _surface, _surface_zenith
from .._shared.checks import PsbenchError, choice
from .._shared.deprecation import renamed_names
from ..registry import Analysis

__all__ = ["ne_vs_surface_zenith", "ie_decomposition", "ne_vs_image_count",
           "ne_vs_source_zenith", "propose_zeniths", "wps_table", "table_5_5", "table_5_6",
           "mask_scores", "highlight_truth_options", "diffuse_counts", "forensic", "breechface",
           "IMAGE_KINDS", "TRUTHS"]

_COUNTS_5_5 = (8, 12, 16, 24, 32)
#: highlight ground-truth definitions compared by :func:`mask_scores` (labels of
#: :func:`highlight_truth_options`): psbench's default reflection cone of 12 deg, the
#: earlier range cut-off 0.1 and the range cut-off 0.5
TRUTHS = ("cone12", "range0.1", "range0.5")


# ----------------------------------------------------------------------------- Fig. 4.9
def ne_vs_surface_zenith(surface="sombrero2", lights=("30x8", "45x8", "60x8"), *, size=128,
                         kind="Hi-Sh", noise=0.05, seed=0, mask="None", bins=None):
    """Mean NE versus true surface zenith for one or more layouts (Fig. 4.9).

    Parameters
    ----------
    surface : str or Surface
    lights : str, Layout or sequence of them
        One curve per layout (default: single rings at 30, 45, 60 degrees, 8 lights).
    size : int
    kind : {"Hi-Sh", "Di", "Di-clamped"}
    noise : float
    seed : int
    mask : str
        Mask of the PS solve (default plain PS).
    bins : int or edges (degrees), optional
        Default 5-degree bins over [0, 90].

    Returns
    -------
    pandas.DataFrame
        Columns ``surface, lights, source_zenith`` (mean light zenith), ``zenith``
        (bin centre), ``lo, hi, ne`` (mean NE in the bin, deg), ``count`` (pixels).
    """
    import pandas as pd
    from ..lights import layout
    from ..metrics.errors import ne_by_zenith

    surf = _surface(surface, size)
    frames = []
    for spec in _seq(lights):
        lay = layout(spec)
        sc = _render(surf, lay, kind, noise, seed)
        res = _ps(sc.images, lay, mask=mask, object_mask=surf.object_mask)
        df = ne_by_zenith(res.normals, surf.normals, object_mask=surf.object_mask,
                          bins=_edges(bins))
        df.insert(0, "source_zenith", float(np.mean(lay.zenith)))
        df.insert(0, "lights", lay.name)
        df.insert(0, "surface", _sname(surf, surface))
        frames.append(df)
    return pd.concat(frames, ignore_index=True)


# ----------------------------------------------------------------------------- Figs. 4.6, 4.10
def ie_decomposition(surface="sombrero2", zeniths=(20, 30, 40, 45, 50, 60, 70, 80), *,
                     count=8, size=128, by="source", bins=None, rho_s=1.0, m=2.0, seed=0):
    """Intensity error of TS images split into highlight, self-shadow and cast-shadow
    parts (Eq. 4.1), versus source zenith (Fig. 4.6) or surface zenith (Fig. 4.10).

    The error of an observation is its deviation from the *linear* Lambert model of
    the true normal, ``E = I - rho_d s . n`` (noise-free). It splits into disjoint parts:

    * ``highlight``: the specular term (lit, unshadowed observations; Eq. 4.1 line 1),
    * ``self_shadow``: ``-rho_d s . n`` where ``s . n < 0`` (Eq. 4.1 line 2),
    * ``cast_shadow``: ``rho_d s . n`` lost where the point is occluded (omitted in
      Eq. 4.1, reported here),

    and ``total`` = mean |E| = the sum of the parts' mean absolute values (L1 over
    observations, so the parts add up).

    Parameters
    ----------
    surface : str or Surface
    zeniths : sequence of float
        Source zeniths (degrees), one ring of ``count`` lights each.
    count : int
    size : int
    by : {"source", "surface"}
        "source": one value per zenith and part, averaged over the object's pixels and
        the images. "surface": additionally binned by the true surface zenith.
    bins : int or edges, optional
        Surface-zenith bins for ``by="surface"`` (default 5 degrees).
    rho_s, m : float
        TS specular albedo and roughness (Table 5.1: 1 and 2).
    seed : int

    Returns
    -------
    pandas.DataFrame
        Columns ``surface, source_zenith, [zenith, lo, hi, pixels,] part, ie, ie_rel``
        with ``ie`` the mean absolute error in intensity units and ``ie_rel`` in percent
        of the mean image dynamic range (of the rendered images over the object).
    """
    import pandas as pd
    from ..lights import layout
    from ..render.scene import render
    from ..solve import kernel

    by = choice(by, ("source", "surface"), "by")
    surf = _surface(surface, size)
    obj = np.asarray(surf.object_mask, dtype=bool)
    zs = _surface_zenith(surf)[obj]
    edges = _edges(bins)
    rows = []
    for z in _seq(zeniths):
        lay = layout(_ring(z, count))
        sc = render(surf, lay, model="ts", shadows=True, noise=0.0, seed=seed, rho_s=rho_s, m=m)
        lin = np.asarray(kernel.lambert(np.asarray(surf.normals, np.float32), lay.S))
        spec = np.asarray(sc.specular)
        ss = np.asarray(sc.self_shadow)
        cs = np.asarray(sc.cast_shadow) & ~ss
        parts = {
            "highlight": np.abs(spec)[:, obj],
            "self_shadow": np.where(ss, np.abs(lin), 0.0)[:, obj],
            "cast_shadow": np.where(cs, np.abs(lin), 0.0)[:, obj],
        }
        parts["total"] = parts["highlight"] + parts["self_shadow"] + parts["cast_shadow"]
        dr = float(np.mean(sc.dynamic_range))
        if by == "source":
            for name, v in parts.items():
                ie = float(v.mean())
                rows.append(dict(surface=_sname(surf, surface), source_zenith=float(z), part=name,
                                 ie=ie, ie_rel=100.0 * ie / dr if dr > 0 else np.nan))
        else:
            idx = np.searchsorted(edges, zs, side="right") - 1
            idx[zs == edges[-1]] = edges.size - 2
            ok = (idx >= 0) & (idx < edges.size - 1)
            nb = edges.size - 1
            cnt = np.bincount(idx[ok], minlength=nb)
            for name, v in parts.items():
                per_pixel = v.mean(axis=0)
                tot = np.bincount(idx[ok], weights=per_pixel[ok], minlength=nb)
                with np.errstate(invalid="ignore", divide="ignore"):
                    mean = np.where(cnt > 0, tot / np.maximum(cnt, 1), np.nan)
                for b in range(nb):
                    rows.append(dict(surface=_sname(surf, surface), source_zenith=float(z),
                                     zenith=0.5 * (edges[b] + edges[b + 1]), lo=edges[b],
                                     hi=edges[b + 1], pixels=int(cnt[b]), part=name,
                                     ie=float(mean[b]),
                                     ie_rel=100.0 * float(mean[b]) / dr if dr > 0 else np.nan))
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- Fig. 4.3
def ne_vs_image_count(surface="sombrero2", counts=(4, 6, 8, 12, 16, 24, 32), *, zenith=45,
                      kinds=("Di", "Hi-Sh"), size=128, noise=0.05, seed=0, mask="None"):
    """NE versus image count n_i for one source zenith (Fig. 4.3).

    Returns
    -------
    pandas.DataFrame
        Columns ``surface, kind, zenith, count, lights, ne``.
    """
    return ne_vs_source_zenith(surface, zeniths=(zenith,), counts=counts, kinds=kinds,
                               size=size, noise=noise, seed=seed, mask=mask)


# ----------------------------------------------------------------------------- Figs. 4.4, 4.7
def ne_vs_source_zenith(surface="sombrero2", zeniths=tuple(range(20, 85, 5)), *,
                        counts=(8,), kinds=("Di", "Hi-Sh"), size=128, noise=0.05, seed=0,
                        mask="None"):
    """NE versus source zenith for single-ring layouts (Fig. 4.4: Di, several counts;
    Fig. 4.7: Di and Hi-Sh per sombrero).

    Returns
    -------
    pandas.DataFrame
        Columns ``surface, kind, zenith, count, lights, ne``.
    """
    import pandas as pd
    from ..lights import layout

    surf = _surface(surface, size)
    rows = []
    for kind in _seq(kinds):
        for n in _seq(counts):
            for z in _seq(zeniths):
                lay = layout(_ring(z, n))
                sc = _render(surf, lay, kind, noise, seed)
                res = _ps(sc.images, lay, mask=mask, object_mask=surf.object_mask)
                rows.append(dict(surface=_sname(surf, surface), kind=kind, zenith=float(z),
                                 count=int(n), lights=lay.name, ne=_ne(res.normals, surf)))
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- Eq. 4.2
def propose_zeniths(std_h=15.0, z_opt=45.0):
    """Rule of thumb of Eq. 4.2 for double-zenith lights.

    Solves ``Z1/2 + std_h = 90 - Z2`` and ``(Z1 + Z2)/2 = z_opt``:
    ``Z1 = 2 (2 z_opt + std_h - 90)``, ``Z2 = 2 z_opt - Z1``.

    Parameters
    ----------
    std_h : float
        Spread (degrees) of the highlight error around Z_surface = Z1/2.
    z_opt : float
        Optimal single-ring zenith without highlights and shadows (45).

    Returns
    -------
    (float, float)
        (Z1, Z2) in degrees; (30, 60) for the defaults.
    """
    std_h, z_opt = float(std_h), float(z_opt)
    z1 = 2.0 * (2.0 * z_opt + std_h - 90.0)
    z2 = 2.0 * z_opt - z1
    if not (0.0 < z1 < z2 < 90.0):
        raise PsbenchError(
            f"propose_zeniths(std_h={std_h:g}, z_opt={z_opt:g}) gives Z1={z1:g}, Z2={z2:g}; "
            "expected 0 < Z1 < Z2 < 90 (use a smaller std_h or a z_opt nearer 45)")
    return z1, z2


# ----------------------------------------------------------------------------- Tables 5.5 / 5.6
def wps_table(surfaces=("sombrero1", "sombrero2", "sombrero3"), counts=_COUNTS_5_5, *,
              weights=("None", "e", "eZsource", "eZsurface", "eZsourceZsurface"),
              binary=(False, True), oracle=False, size=128, noise=0.05, seed=0,
              z_single=45.0, zeniths=(30.0, 60.0), kind="Hi-Sh", render_options=None):
    """The data of Tables 5.5 and 5.6: 1Z PS versus 2Z PS and WPS.

    For each surface and image count n: 1Z = ``{z_single}x{n}`` solved with plain PS;
    2Z = ``{Z1}x{n/2}+{Z2}x{n/2}`` solved with plain PS over all images
    (``weight="None"``) and with WPS for every weight in ``weights`` (weighted and,
    with ``binary`` containing True, binary). Both configurations are rendered with the
    same seed.

    Parameters
    ----------
    surfaces : sequence of str
    counts : sequence of even int
    weights : sequence of str
        WPS weight definitions ("None" = 2Z plain PS).
    binary : sequence of bool
    oracle : bool
        Also the oracle limit (Fig. 4.11e).
    size : int
    noise : float
    seed : int
    z_single : float
    zeniths : (float, float)
    kind : {"Hi-Sh", "Di", "Di-clamped"}
    render_options : dict, optional
        Further keyword options of :func:`psbench.render.render` (e.g. ``{"m": 4}``).

    Returns
    -------
    pandas.DataFrame
        Tidy rows ``surface, count, source ("1Z"/"2Z"), lights, weight, binary, ne``.
        :func:`table_5_5` and :func:`table_5_6` pivot it.
    """
    import pandas as pd
    from ..lights import layout
    from ..solve.methods.wps import WEIGHTS, wps

    for w in _seq(weights):
        choice(w, WEIGHTS, "weights")
    z1, z2 = (float(z) for z in zeniths)
    ro = dict(render_options or {})
    rows = []
    wlist = list(_seq(weights)) + (["oracle"] if oracle else [])
    for name in _seq(surfaces):
        surf = _surface(name, size)
        for n in _seq(counts):
            n = int(n)
            if n % 2 or n < 6:
                raise PsbenchError(f"counts must be even and >= 6 (two rings of >= 3), got {n}")
            lay1 = layout(_ring(z_single, n))
            sc1 = _render(surf, lay1, kind, noise, seed, **ro)
            r1 = _ps(sc1.images, lay1, object_mask=surf.object_mask)
            rows.append(dict(surface=_sname(surf, name), count=n, source="1Z", lights=lay1.name,
                             weight="None", binary=False, ne=_ne(r1.normals, surf)))
            lay2 = layout(f"{_ring(z1, n // 2)}+{_ring(z2, n // 2)}")
            sc2 = _render(surf, lay2, kind, noise, seed, **ro)
            for w in wlist:
                for b in (_seq(binary) if w != "None" else [False]):
                    r = wps(sc2.images, lay2, weight=w, binary=bool(b), object_mask=surf.object_mask,
                            truth_normals=surf.normals if w == "oracle" else None)
                    rows.append(dict(surface=_sname(surf, name), count=n, source="2Z",
                                     lights=lay2.name, weight=w, binary=bool(b),
                                     ne=_ne(r.normals, surf)))
    return pd.DataFrame(rows)


def table_5_5(df, *, binary=False):
    """Pivot :func:`wps_table` output into Table 5.5: mean NE over surfaces, rows
    (source, weight), columns count, plus the improvement (%) over 1Z PS.

    Returns
    -------
    (ne, improvement) : two pandas.DataFrame
    """
    d = df[(df["binary"] == binary) | (df["weight"] == "None")]
    ne = d.pivot_table(index=["source", "weight"], columns="count", values="ne", aggfunc="mean")
    order = [("1Z", "None")] + [("2Z", w) for w in ("None", "e", "eZsource", "eZsurface",
                                                    "eZsourceZsurface", "oracle")]
    ne = ne.reindex([o for o in order if o in ne.index])
    base = ne.loc[("1Z", "None")]
    imp = 100.0 * (base - ne) / base
    return ne, imp.drop(index=("1Z", "None"))


def table_5_6(df, *, weight="eZsourceZsurface", count=16):
    """Pivot :func:`wps_table` output into Table 5.6: NE per surface (and mean) for the
    weighted and binary WPS with ``weight`` and ``count`` images."""
    d = df[(df["weight"] == weight) & (df["count"] == count) & (df["source"] == "2Z")]
    t = d.pivot_table(index="binary", columns="surface", values="ne", aggfunc="mean")
    t["Mean"] = t.mean(axis=1)
    t.index = ["Binary" if b else "Weighted" for b in t.index]
    return t.reindex([i for i in ("Weighted", "Binary") if i in t.index])


# ----------------------------------------------------------------------------- Tables 5.2 / 5.3
def highlight_truth_options(label):
    """Render options of a highlight ground-truth label: ``"cone<t>"`` (reflection cone,
    half-angle t degrees) or ``"range<f>"`` (specular term above f x the image range),
    e.g. ``"cone12"`` -> ``{"highlight": "cone", "highlight_angle": 12.0}``."""
    import re

    m = re.fullmatch(r"(cone|range)(\d+(?:\.\d*)?)", str(label))
    if not m:
        raise PsbenchError(f"highlight truth {label!r} is not known; expected 'cone<degrees>' "
                           "or 'range<fraction>', e.g. cone12, range0.5")
    v = float(m.group(2))
    key = "highlight_angle" if m.group(1) == "cone" else "highlight_fraction"
    return {"highlight": m.group(1), key: v}


def mask_scores(surface="sombrero2", lights="45x8", *, cases=None, mask="Th", thresholds=None,
                weighted=False, th_scope="image", th_scopes=(), model="ts", shadows=True,
                noise=0.05, size=128, seed=0, truths=TRUTHS, render_options=None):
    """Render one scene, solve it with several masks (or thresholds) and score each: NE,
    solve time and the quality factor (Eq. 2.32) under several highlight ground-truth
    definitions (the thesis does not define it; Table 5.2 tunes on QF).

    Parameters
    ----------
    surface : str or Surface
    lights : str or Layout
    cases : sequence of dict, optional
        One solve each: ``{"mask": str, "thresholds": dict, "weighted": bool, "th_scope":
        str}`` (missing keys: the arguments below). Default: one case from ``mask``,
        ``thresholds``, ``weighted``, ``th_scope``.
    mask, thresholds, weighted, th_scope
        Defaults of the cases (as :func:`psbench.solve`).
    th_scopes : sequence of str
        Further Th range scopes: every case whose mask contains Th is solved once more
        with each (e.g. ``("object", "robust", "pixel")``).
    model, shadows, noise, size, seed
        The scene (as :func:`psbench.render.render`; ``seed`` also seeds RA).
    truths : sequence of str
        Highlight ground-truth labels (:func:`highlight_truth_options`); the first is
        the one the scene is rendered with (the images do not depend on it).
    render_options : dict, optional
        Further keyword options of :func:`psbench.render.render` (e.g. ``{"m": 4}``, the
        Torrance-Sparrow lobe width).

    Returns
    -------
    pandas.DataFrame
        One row per case and truth: ``case, mask, thresholds`` (json), ``weighted,
        th_scope, truth, n_images, ne_mean, ne_median, t_solve, qf_hi, qf_sh, qf_total``.
    """
    import json
    import time

    import pandas as pd
    from ..lights import layout
    from ..metrics.errors import normal_error_stats, quality_factor
    from ..render.scene import render

    truths = [str(t) for t in _seq(truths)]
    opts = [highlight_truth_options(t) for t in truths]
    if not truths:
        raise PsbenchError("truths must name at least one highlight ground truth")
    base = dict(mask=mask, thresholds=thresholds or {}, weighted=weighted, th_scope=th_scope)
    cases = [dict(base)] if cases is None else [{**base, **dict(c)} for c in _seq(cases)]
    cases += [{**c, "th_scope": str(sc)} for sc in _seq(th_scopes) for c in list(cases)
              if "Th" in str(c["mask"]).split("-") and str(sc) != c["th_scope"]]
    ro = dict(render_options or {})
    bad = sorted(set(ro) & {"model", "shadows", "noise", "seed", "highlight",
                            "highlight_angle", "highlight_fraction"})
    if bad:
        raise PsbenchError(f"render_options must not set {bad}: they are arguments of "
                           "mask_scores (truths for the highlight ground truth)")
    surf = _surface(surface, size)
    lay = layout(lights)
    sc = render(surf, lay, model=model, shadows=shadows, noise=noise, seed=seed, **opts[0], **ro)
    gts = [sc.highlight] + [sc.highlight_truth(**o) for o in opts[1:]]
    obj = surf.object_mask
    rows = []
    for i, c in enumerate(cases):
        t0 = time.perf_counter()
        res = _ps(sc.images, lay, mask=c["mask"], object_mask=obj, seed=seed,
                  thresholds=c["thresholds"] or None, weighted=bool(c["weighted"]),
                  th_scope=c["th_scope"])
        t = time.perf_counter() - t0
        st = normal_error_stats(res.normals, surf.normals, object_mask=obj)
        flagged = ~np.asarray(res.valid, dtype=bool)
        for label, gt in zip(truths, gts):
            qf = quality_factor(flagged, {"highlight": gt, "self_shadow": sc.self_shadow,
                                          "cast_shadow": sc.cast_shadow}, object_mask=obj)
            rows.append(dict(case=i, mask=c["mask"], thresholds=json.dumps(
                c["thresholds"] or {}, sort_keys=True), weighted=bool(c["weighted"]),
                th_scope=c["th_scope"], truth=label, n_images=lay.k,
                ne_mean=float(st["mean"]), ne_median=float(st["median"]), t_solve=t,
                qf_hi=float(qf["hi"]), qf_sh=float(qf["sh"]), qf_total=float(qf["total"])))
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- Fig. 5.8
def diffuse_counts(surface="sombrero2", lights=("30x4", "45x4", "60x4"), *, size=256,
                   truths=("cone12",), model="ts"):
    """How many diffuse observations (neither highlight nor shadow) each pixel has, per
    layout and highlight ground truth (thesis Fig. 5.8: with 4 lights every sombrero and
    sphere pixel has 2, 3 or 4). Noise-free renders with self and cast shadows.

    Returns
    -------
    pandas.DataFrame
        One row per layout and truth: ``surface, lights, truth, highlight`` (fraction of
        lit observations that are highlights), ``shadow_only_lt2`` (fraction of pixels
        with < 2 unshadowed observations), ``d0 .. d<k>`` (fraction of pixels with that
        many diffuse observations) and ``nondiffuse`` (mean non-diffuse observations per
        pixel).
    """
    import pandas as pd
    from ..lights import layout
    from ..render.scene import render

    surf = _surface(surface, size)
    obj = np.asarray(surf.object_mask, dtype=bool)
    rows = []
    for spec in _seq(lights):
        lay = layout(spec)
        sc = render(surf, lay, model=model, noise=0.0)
        sh = sc.shadow
        lit = (~sh)[:, obj]
        base = float((lit.sum(axis=0) < 2).mean())
        for t in _seq(truths):
            hi = sc.highlight_truth(**highlight_truth_options(t))
            d = (~hi & ~sh).sum(axis=0)[obj]
            row = dict(surface=_sname(surf, surface), lights=lay.name, truth=str(t),
                       highlight=float(hi[:, obj].sum() / max(lit.sum(), 1)),
                       shadow_only_lt2=base, nondiffuse=float(lay.k - d.mean()))
            row.update({f"d{i}": float(c) for i, c in
                        enumerate(np.bincount(d, minlength=lay.k + 1) / d.size)})
            rows.append(row)
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- Chapter 7
def forensic(part="method", label=None, *, size=1024, seed=0, study=None):
    """Chapter 7 forensic study: one part (method, truth, timing, panels) of experiment
    chapter7 (:func:`psbench.forensic.study.run`; payload json)."""
    from ..forensic.study import run

    return run(part, label, size=size, seed=seed, study=study)


def breechface(part="method", label=None, *, finish=None, integrator=None, seed=0,
               study=None):
    """Real breech-face study: one part (method, scan, panels) of experiment breechface
    (:func:`psbench.forensic.breechface_runs.run`; payload json)."""
    from ..forensic.breechface_runs import run

    return run(part, label, finish=finish, integrator=integrator, seed=seed, study=study)


# ----------------------------------------------------------------------------- registry
def _spec(func, operational=()):
    return Analysis(name=func.__name__, func=func,
                    help=(func.__doc__ or "").strip().split("\n")[0], operational=operational)


#: psbench's own ``kind=analysis`` computations, registered like a plug-in's (the
#: ``psbench.analyses`` group of :mod:`psbench.registry`)
#: (breechface's cache, table of earlier comparisons and process count say how its runs
#: are computed, not what they compute: they are not part of a run's id)
ANALYSES = (_spec(breechface, operational=("cache", "pairs_table", "jobs")),) + tuple(
    _spec(f) for f in (
        diffuse_counts, forensic, highlight_truth_options, ie_decomposition, mask_scores,
        ne_vs_image_count, ne_vs_source_zenith, ne_vs_surface_zenith, propose_zeniths,
        table_5_5, table_5_6, wps_table))


__getattr__ = renamed_names(globals(), {"KINDS": "IMAGE_KINDS"})
