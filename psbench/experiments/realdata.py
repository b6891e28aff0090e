"""Real photographs: every method and the Table 5.3 masks on DiLiGenT-layout folders.

The grid (``realdata.yaml``) lists the folders of a data root with the OmegaConf resolver
``psbench_folders`` registered here: every sub-folder holding a ``filenames.txt`` (the
DiLiGenT layout), sorted by name; the root itself when it is such a folder; else the root
(its runs then fail with a message naming it, listed on the page). The ``ci`` scale runs
the same grid on copies of those folders reduced 4x in each image axis (block means;
made by :func:`prepare` under ``<results>/realdata_ci``, resolver ``psbench_ci_folders``).
"""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd

from psbench.report.aggregates import data_name, long_frame
from psbench.report.verdicts import (NE_MARGIN, lowest, nodata, num, own_questions,
                                     part_values, verdict)

TITLE = "Real photographs: robust methods and the thesis's masks on DiLiGenT objects"
AVERAGES = ("Mean angular error (deg) over each object's mask against its ground-truth "
            "normals, one run per object, method and light set; t_solve (s) of the "
            "whole solve on this machine. 'mean' averages the objects.")
NOTES = ("The 'thesis' column holds the published DiLiGenT values of cat and bear "
         "(Shi et al., TPAMI 2019: L2 = least squares over all 96 images, ST14 = Shi et al. "
         "2014), not values of the thesis; psbench's row 'None' (least squares) must "
         "reproduce L2. Light sets: all lights; '30x8+60x8' = for each of the 16 "
         "directions of the two rings the nearest unused light of the folder, most certain "
         "matches first (DiLiGenT's lights stop at ~43 deg zenith, so its '60 deg' ring is "
         "its outermost lights); '45x4' the same for a 45-degree ring of four. tsfit needs "
         "5 images (not run on 45x4); NL-Re, NL-Re-Sh and CJ need exactly 4 (45x4 only). "
         "Rows 'Th[robust]', 'Th[pixel]' use th_scope=robust / pixel (robust image ranges,"
         " per-pixel order statistics) and 'Th[keep=0.5]' the th_keep option: the robust "
         "threshold options, beside the literal rule (the default). The ci scale runs the "
         "same grid on the folders reduced 4x per axis (block means), so its numbers are not"
         " DiLiGenT's. Times: shared 2-core machine, compare ratios.")
GATED = False

#: published DiLiGenT mean angular errors (deg), all 96 lights
PUBLISHED = {"L2": {"cat": 8.41, "bear": 8.39}, "ST14": {"cat": 6.12, "bear": 6.12}}
LIGHT_SETS = ("all", "30x8+60x8", "45x4")
THESIS = {"NE all": {"None": dict(PUBLISHED["L2"]),
                     "ST14 (published)": dict(PUBLISHED["ST14"])}}
#: robust solvers of the literature (mask None)
LITERATURE = ("trim", "huber", "cauchy", "tukey", "l1", "sbl", "rpca")
#: the thesis's masks with ordinary PS (Table 5.3), the literal rule
MASKS = ("xNL", "Th", "Re", "SS", "Sh", "Hi-Re", "Hi-Re-SS-Sh", "Hi-Re-Sh", "CS", "xNL-Sh",
         "xNL-Re-Sh", "xNL-Hi-Sh", "xNL-Hi-Re-Sh", "Th-Re-Sh", "Th-Hi-Sh", "Th-Hi-Re-Sh",
         "Th-Hi-Re-SS-Sh", "RA", "NL-Re", "NL-Re-Sh", "CJ")
PART_TITLES = {**{f"NE {s}": f"Mean angular error (deg), {s} lights" for s in LIGHT_SETS},
               **{f"time {s}": f"Solve time (s), {s} lights" for s in LIGHT_SETS}}
TABLE_AXES = {"*": ("method (mask for ps rows; method[mask] when composed)", "object")}
CI_FACTOR = 4


def cell_kind(part, column):
    return "time" if part.startswith("time") else "ne"


# ------------------------------------------------------------------------ data folders
def _is_dataset(p: Path) -> bool:
    return (p / "filenames.txt").is_file()


def folders(root) -> list[str]:
    """DiLiGenT-layout folders at or directly under ``root`` (see the module docstring)."""
    root = Path(str(root))
    if _is_dataset(root):
        return [str(root)]
    subs = sorted(p for p in root.iterdir() if p.is_dir() and _is_dataset(p)) \
        if root.is_dir() else []
    return [str(p) for p in subs] or [str(root)]


def ci_folders(root, dest) -> list[str]:
    """Where :func:`prepare` puts the reduced copy of each folder of ``root``."""
    return [str(Path(str(dest)) / Path(f).name) for f in folders(root)]


def _register_resolvers():
    from omegaconf import OmegaConf

    OmegaConf.register_new_resolver("psbench_folders", folders, replace=True)
    OmegaConf.register_new_resolver("psbench_ci_folders", ci_folders, replace=True)


_register_resolvers()      # the grid refers to them; loading the grid imports this module


def _reduce(src: Path, dst: Path, f: int) -> None:
    """A copy of a DiLiGenT-layout folder with images block-averaged f x f (mask: blocks
    wholly inside it; normals: block means renormalized)."""
    from psbench.io import read_dataset, write_dataset

    ds = read_dataset(src)
    k, H, W = ds.images.shape
    h, w = H // f, W // f

    def blocks(a):
        return a[..., :h * f, :w * f].reshape(*a.shape[:-2], h, f, w, f)

    images = blocks(ds.images.astype(np.float32)).mean(axis=(-3, -1))
    om = blocks(np.asarray(ds.object_mask, bool)).all(axis=(-3, -1))
    normals = None
    if ds.normals is not None:
        n = blocks(np.moveaxis(np.asarray(ds.normals, np.float32), -1, 0)).mean(axis=(-3, -1))
        n = np.moveaxis(n, 0, -1)
        n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
        normals = n
    write_dataset(dst, np.clip(images, 0, 1), ds.lights, object_mask=om, normals=normals,
                  names=list(ds.names) if ds.names is not None else None, overwrite=True,
                  meta={"reduced_from": src.name, "factor": f})


def prepare(root, scale):
    """ci scale: make the reduced copies of the data root's folders under
    ``<root>/realdata_ci`` when missing (deterministic, atomic)."""
    if scale != "ci":
        return
    import os

    src = os.environ.get("PSBENCH_REALDATA") or \
        f"{os.environ.get('PSBENCH_DATA', '../shared/data')}/diligent"
    for f, d in zip(folders(src), ci_folders(src, Path(root) / "realdata_ci")):
        if _is_dataset(Path(f)) and not _is_dataset(Path(d)):
            _reduce(Path(f), Path(d), CI_FACTOR)


# --------------------------------------------------------------------------- aggregate
def _opt(v) -> dict:
    if isinstance(v, dict):
        return v
    if isinstance(v, str) and v.strip().startswith("{"):
        try:
            return json.loads(v)
        except ValueError:
            return {}
    return {}


def label(r) -> str:
    """Row label: the method (mask None), the mask (ordinary PS), method[mask] when
    composed; robust threshold options in brackets (Th[robust], Th[keep=0.5])."""
    method, mask = str(r.get("method") or "ps"), str(r.get("mask") or "None")
    extra = []
    scope = r.get("th_scope")
    if isinstance(scope, str) and scope not in ("", "image"):
        extra.append(scope)
    for k, v in sorted(_opt(r.get("thresholds")).items()):
        extra.append(f"{k.removeprefix('th_')}={v:g}" if isinstance(v, float) else f"{k}={v}")
    base = mask if method == "ps" else (method if mask == "None" else f"{method}[{mask}]")
    return f"{base}[{','.join(extra)}]" if extra else base


def light_set(r) -> str:
    v = r.get("lights")
    return "all" if v is None or (isinstance(v, float) and math.isnan(v)) or v in ("", "None") \
        else str(v)


def aggregate(rows):
    """NE and time per (light set, row label, object), plus the mean over objects."""
    if rows is None or rows.empty:
        return long_frame([])
    d = rows.copy()
    d["_row"] = [label(r) for r in d.to_dict("records")]
    d["_set"] = [light_set(r) for r in d.to_dict("records")]
    d["_obj"] = [data_name(x) for x in d.get("data", [None] * len(d))]
    recs = []
    for col, part in (("ne_mean", "NE"), ("t_solve", "time")):
        if col not in d:
            continue
        d[col] = pd.to_numeric(d[col], errors="coerce")
        for (s, lab), g in d.groupby(["_set", "_row"]):
            per = g.groupby("_obj")[col].mean().dropna()
            for o, v in per.items():
                recs.append((f"{part} {s}", lab, o, float(v), int((g["_obj"] == o).sum())))
            if len(per):
                recs.append((f"{part} {s}", lab, "mean", float(per.mean()), int(len(g))))
    return long_frame(recs)


# ---------------------------------------------------------------------------- verdicts
def _objects(agg, part):
    return sorted(c for c in agg.loc[agg["part"] == part, "column"].unique() if c != "mean")


def _col(agg, part, column):
    return part_values(agg, part, column)


def _best_of(values, names):
    got = {k: v for k, v in values.items() if k in names}
    if not got:
        return None, float("nan")
    k = min(got, key=got.get)
    return k, got[k]


def beats(claim, values, who, others, what="best of the others"):
    """``who`` is below the best of ``others`` by at least NE_MARGIN (INCONCLUSIVE within it)."""
    if who not in values:
        return nodata(claim)
    k, b = _best_of(values, others)
    if k is None:
        return nodata(claim)
    gap = b - values[who]
    return verdict(claim, gap > 0, f"{who} {num(values[who])} deg vs {what} {k} {num(b)} deg",
                   undecided=abs(gap) < NE_MARGIN)


@own_questions
def verdicts(agg, rows=None):
    """The conclusions the real-data table supports or not, per light set and object."""
    claims = ["robust beats every thesis mask on every object (all lights)",
              "robust beats the published ST14 on cat and bear (all lights)",
              "Modelling the highlight (tsfit) beats masking it (best thesis mask), all lights",
              "A robust threshold option makes Th more accurate than the literal rule"]
    if agg is None or agg.empty:
        return [nodata(c) for c in claims]
    out = []
    for s in LIGHT_SETS:
        part = f"NE {s}"
        for o in _objects(agg, part):
            vals = _col(agg, part, o)
            if s == "all" or "robust" in vals:
                out.append(beats(f"robust beats every thesis mask on {o} ({s} lights)", vals,
                                 "robust", MASKS, "best thesis mask"))
    st = [(o, _col(agg, "NE all", o).get("robust")) for o in ("cat", "bear")]
    st = [(o, v) for o, v in st if v is not None]
    if st:
        out.append(verdict(claims[1], all(v < PUBLISHED["ST14"][o] for o, v in st),
                           ", ".join(f"{o}: robust {num(v)} vs ST14 {PUBLISHED['ST14'][o]}"
                                     for o, v in st),
                           undecided=any(abs(v - PUBLISHED["ST14"][o]) < NE_MARGIN
                                         for o, v in st)))
    else:
        out.append(nodata(claims[1]))
    for s in ("all", "30x8+60x8"):
        part = f"NE {s}"
        for o in _objects(agg, part):
            out.append(beats(f"Modelling the highlight (tsfit) beats masking it (best thesis"
                             f" mask) on {o} ({s} lights)", _col(agg, part, o), "tsfit",
                             MASKS, "best thesis mask"))
            lit = {k: v for k, v in _col(agg, part, o).items() if k in LITERATURE + ("robust",)}
            out.append(lowest(f"robust is the most accurate robust solver on {o} ({s} lights)",
                              lit, "robust"))
    part = "NE 30x8+60x8"
    for o in _objects(agg, part):
        v = _col(agg, part, o)
        if "None" not in v or "Th" not in v:
            continue
        rob = {k: x for k, x in v.items() if k.startswith("Th[")}
        best = min(rob, key=rob.get) if rob else None
        detail = f"None {num(v['None'])}, Th (literal) {num(v['Th'])}" + \
            (f", best option {best} {num(rob[best])} deg" if best else "")
        out.append(verdict(f"A robust threshold option makes Th more accurate than the "
                           f"literal rule on {o} (16-light rig)",
                           bool(best) and rob[best] < v["Th"], detail,
                           undecided=not best or abs(rob[best] - v["Th"]) < NE_MARGIN))
    return out or [nodata(c) for c in claims]


# ----------------------------------------------------------------------------- figures
#: light sets drawn as grids of per-pixel error maps (one figure per object and set)
MAP_SETS = ("all", "30x8+60x8")
MAP_COLS = 8             # panels per row of a map grid
MAP_OUTSIDE = "#c8c8c8"  # colour of the pixels outside the object


def error_maps(rows, lights="all") -> dict:
    """``{object: [(row label, mean NE, (h, w) map)]}`` of the rows carrying an ``ne_map``
    (light set ``lights``), sorted by mean NE; maps cropped to the object's box (shared by the
    object's maps). Rows without a map (older stores) are left out."""
    from psbench.harness.nemap import decode

    if rows is None or len(rows) == 0 or "ne_map" not in rows:
        return {}
    d = rows[rows["ne_map"].map(lambda v: isinstance(v, str) and bool(v))]
    got = {}
    for r in d.to_dict("records"):
        if light_set(r) != lights:
            continue
        got.setdefault(data_name(r.get("data")), {}).setdefault(label(r), []).append(
            (pd.to_numeric(r.get("ne_mean"), errors="coerce"), r["ne_map"]))
    out = {}
    for obj, by_label in got.items():
        items = []
        for lab, runs in by_label.items():   # several seeds: mean NE, the first map
            ne = float(np.nanmean([v for v, _ in runs])) if any(v == v for v, _ in runs) \
                else float("nan")
            items.append((lab, ne, decode(runs[0][1])))
        shapes = {m.shape for _, _, m in items}
        if len(shapes) == 1:                 # crop to the object's box, shared by all
            inside = np.any([np.isfinite(m) for _, _, m in items], axis=0)
            if inside.any():
                ys, xs = np.nonzero(inside)
                box = np.s_[max(ys.min() - 1, 0):ys.max() + 2, max(xs.min() - 1, 0):xs.max() + 2]
                items = [(lab, ne, m[box]) for lab, ne, m in items]
        out[obj] = sorted(items, key=lambda t: (not t[1] == t[1], t[1], t[0]))
    return out


def _map_grid(obj, s, items):
    """One figure: the error maps of one object and light set, one colour bar."""
    from matplotlib import colormaps

    from psbench.io._pictures import NE_MAX
    from psbench.report.figures import new_figure

    n = len(items)
    ncols = min(n, MAP_COLS)
    nrows = -(-n // ncols)
    h, w = max(m.shape for _, _, m in items)
    pw = 1.7
    fig, axes = new_figure(w=pw, h=pw * h / w + 0.35, ncols=ncols, nrows=nrows)
    axes = np.atleast_2d(axes)
    # outside the object: light grey, apart from magma's pale yellow (saturated errors)
    cmap = colormaps["magma"].with_extremes(bad=MAP_OUTSIDE)
    im = None
    for ax, (lab, ne, m) in zip(axes.flat, items):
        im = ax.imshow(m, cmap=cmap, vmin=0, vmax=NE_MAX, interpolation="nearest")
        title = f"{lab}  {ne:.2f}°"
        ax.set_title(title if len(title) <= 18 else f"{lab}\n{ne:.2f}°", fontsize=10)
    for ax in axes.flat:
        ax.set_axis_off()
    cb = fig.colorbar(im, ax=axes, shrink=min(1.0, 0.35 + 0.15 * nrows), extend="max",
                      pad=0.01)
    cb.set_label("angular error (deg)")
    fig.suptitle(f"{obj}, {s} lights: per-pixel angular error, sorted by mean NE "
                 f"(grey: outside the object)")
    return fig


def figures(agg, rows=None):
    """Per light set, NE of every row per object (bars), published L2/ST14 marked; with
    ``rows`` carrying ``ne_map``, per object and light set of :data:`MAP_SETS` a grid of
    the per-pixel error maps (magma, 0 to ``NE_MAX`` deg, one colour bar)."""
    from psbench.report.figures import figure_legend, finish, new_figure

    if agg is None or agg.empty:
        return []
    out = []
    for s in LIGHT_SETS:
        part = f"NE {s}"
        a = agg[agg["part"] == part]
        if a.empty:
            continue
        objs = _objects(agg, part)
        order = a[a["column"] == "mean"].sort_values("value")["row"].tolist()
        fig, (ax,) = new_figure(h=max(4.0, 0.22 * len(order) + 1.5))
        y = np.arange(len(order))[::-1]
        hgt = 0.8 / max(1, len(objs))
        for i, o in enumerate(objs):
            vals = [part_values(agg, part, o).get(r, np.nan) for r in order]
            ax.barh(y + 0.4 - hgt * (i + 0.5), vals, hgt, label=o)
            if s == "all" and o in PUBLISHED["ST14"]:
                ax.axvline(PUBLISHED["ST14"][o], color=f"C{i}", ls="--", lw=1,
                           label=f"ST14 published, {o}")
        ax.set_yticks(y, order)
        ax.grid(axis="y", visible=False)
        finish(ax, "mean angular error (deg)", "", f"DiLiGenT objects, {s} lights",
               legend=False)
        figure_legend(fig)
        out.append((f"realdata_{s.replace('+', '_')}", fig))
    for s in MAP_SETS:
        for obj, items in sorted(error_maps(rows, s).items()):
            stem = re.sub(r"[^A-Za-z0-9_.-]", "_", f"realdata_maps_{obj}_{s}")
            out.append((stem, _map_grid(obj, s, items)))
    return out
