"""The blocks of one experiment's page and of the index (see :mod:`psbench.io.html`).

An experiment page opens with its verdicts, then the figures, then the comparison with
the thesis (psbench, thesis and difference in separate columns with units,
:mod:`psbench.report.present`), what was averaged and the grid. The index opens with the
verdict totals (overall and per experiment) and the key findings: the first claim of
every experiment (modules list the thesis's main conclusion first), NOT SUPPORTED first.
"""
from __future__ import annotations

import inspect
import json
import os
from pathlib import Path

import numpy as np
import pandas as pd

from . import present as P
from . import tables as T
from . import verdicts as V
from .aggregates import data_name, parse_json
from ..io.html import STATUSES, Link

__all__ = ["experiment_blocks", "index_blocks", "wall", "display_path", "in_totals",
           "totals"]


#: heading of a page's thesis verdicts (read back by :func:`.scales.page_verdicts`)
VERDICTS_HEADING = "Verdicts on the thesis's conclusions"


def display_path(path) -> str:
    """A store path as shown on a page: relative to the working folder when inside it,
    else its last two components (pages carry no machine-specific absolute paths)."""
    p = Path(path).resolve()
    try:
        return os.path.relpath(p, Path.cwd()) if p.is_relative_to(Path.cwd()) else \
            ".../" + "/".join(p.parts[-2:])
    except (ValueError, OSError):
        return p.name


def _num_sort(values):
    """Numbers in numeric order, anything else in text order: never the store's row
    order, which differs from one run of an experiment to the next."""
    vals = list(dict.fromkeys(values))
    try:
        return sorted(vals, key=float)
    except (TypeError, ValueError):
        return sorted(vals)


def _pstr(v):
    if isinstance(v, float) and v == int(v) and abs(v) < 1e9:
        return str(int(v))
    return str(v)


#: what a render-and-solve run varies; an analysis run (``kind=analysis``) uses none of the
#: scene or solver keys, only its own ``args`` and ``study`` (listed instead)
_RUN_KEYS = ("surface", "data", "lights", "noise", "mask", "method", "weight", "model",
             "shadows", "size", "seed")


def _analysis_keys(rows):
    """The run settings an analysis receives (those its function names: the harness
    passes it no others) and the ``study`` keys it declares operational (how a run is
    computed, not what: left out)."""
    from .. import registry

    specs = registry.analyses()
    keys, operational = ["analysis"], []
    for name in rows["analysis"].dropna().unique():
        if (spec := specs.get(name)) is None:          # a plug-in not installed here
            continue
        keys += [k for k in inspect.signature(spec.func).parameters
                 if k in rows and k not in ("args", "study", "analysis")]
        operational += list(spec.operational or ())
    return list(dict.fromkeys(keys)), set(operational)


def _json_columns(rows, column, skip=()):
    """The keys of a column of JSON objects, as columns (values re-encoded as text)."""
    recs = [r if isinstance(r := parse_json(v), dict) else {} for v in rows.get(column, [])]
    keys = list(dict.fromkeys(k for r in recs for k in r if k not in skip))
    return pd.DataFrame({k: [None if k not in r else r[k] if np.isscalar(r[k])
                             else json.dumps(r[k]) for r in recs] for k in keys},
                        index=rows.index)


def _parameters(rows) -> pd.DataFrame:
    keys = _RUN_KEYS
    if "kind" in rows and len(rows) and (rows["kind"] == "analysis").all():
        own, operational = _analysis_keys(rows)
        args = _json_columns(rows, "args")
        study = _json_columns(rows, "study", skip=operational).add_prefix("study.")
        rows = pd.concat([rows[own], args, study], axis=1)
        keys = list(rows.columns)
    out = []
    for k in keys:
        if k in rows and rows[k].notna().any():
            vals = _num_sort([_pstr(v) if k != "data" else data_name(v)
                              for v in rows[k].dropna().unique()])
            if len(vals) > 12:
                vals = vals[:12] + [f"... ({len(vals)} values)"]
            out.append({"parameter": k, "values": ", ".join(vals)})
    return pd.DataFrame(out, columns=["parameter", "values"])


def wall(rows: pd.DataFrame) -> dict:
    """Run counts and timing of one experiment's stored rows."""
    if rows is None or rows.empty:
        return dict(n=0, ok=0, failed=0, busy=0.0, first=None, last=None, span=0.0)
    t = pd.to_numeric(rows.get("t_total"), errors="coerce")
    if t is None or t.isna().all():
        t = pd.to_numeric(rows.get("t_render"), errors="coerce").fillna(0) + \
            pd.to_numeric(rows.get("t_solve"), errors="coerce").fillna(0)
    utc = pd.to_datetime(rows["utc"], utc=True, errors="coerce").dropna()
    first, last = (utc.min(), utc.max()) if len(utc) else (None, None)
    return dict(n=int(len(rows)), ok=int((rows["status"] == "ok").sum()),
                failed=int((rows["status"] != "ok").sum()), busy=float(np.nansum(t)),
                first=first, last=last,
                span=float((last - first).total_seconds()) if first is not None else 0.0)


def _ts(x):
    return "" if x is None or pd.isna(x) else pd.Timestamp(x).strftime("%Y-%m-%d %H:%M:%S")


def in_totals(name) -> bool:
    """Whether the index counts experiment ``name``'s verdicts (its ``IN_TOTALS``)."""
    try:
        return bool(getattr(T.experiment_module(name), "IN_TOTALS", True))
    except Exception:  # noqa: BLE001 - an experiment no longer installed still counts
        return True


def _tally(vs) -> dict:
    return {s: sum(v.status == s for v in vs) for s in STATUSES}


def _comparison_blocks(name, cmp) -> list:
    mod = T.experiment_module(name)
    timed = any(P.cell_kind(name, p, c) == "time" for p, c in zip(cmp["part"], cmp["column"]))
    blocks = [("h2", "psbench vs thesis"),
              ("p", "psbench: this report's mean over the runs named above; thesis: the value "
                    "the thesis prints; Δ = psbench − thesis, in the column's unit; — : no "
                    "value." + (" Times are compared as ratios to the unmasked solve (None) "
                                "of the same runs, never as seconds (the thesis timed Matlab "
                                "on other hardware)." if timed else ""))]
    hidden = set(getattr(mod, "HIDDEN_PARTS", ()))
    parts = list(dict.fromkeys(cmp["part"]))
    measured = set(cmp.loc[cmp["psbench"].notna(), "part"])
    parts = [p for p in parts if p in measured] + [p for p in parts if p not in measured]
    for part in parts:
        if part in hidden:
            blocks.append(("p", f"Part `{part}` ({int((cmp['part'] == part).sum())} cells) is "
                                f"plotted above and listed in `data/{name}.csv`."))
            continue
        if part or len(parts) > 1:
            blocks.append(("h3", P.part_title(name, part)))
        table, caption = P.part_table(name, cmp, part)
        blocks.append(("table", table, caption))
    return blocks


def experiment_blocks(name, scale, size, rows_all, agg, cmp, verdicts, figs,
                      results=None, grid_runs=None) -> list:
    """Blocks of one experiment's page; ``figs`` = ``[(relpath, stem), ...]``;
    ``grid_runs`` = ``(present, expected)`` runs of the current grid (None: unknown)."""
    mod = T.experiment_module(name)
    ok = rows_all[rows_all["status"] == "ok"] if not rows_all.empty else rows_all
    failed = rows_all[rows_all["status"] != "ok"] if not rows_all.empty else rows_all
    desc = str(T.grid(name, results).get("description", "") or "").strip()
    notes = getattr(mod, "NOTES", "")
    blocks = [("h1", T.title(name))]
    if grid_runs and grid_runs[0] < grid_runs[1]:
        blocks.append(("p", f"**INCOMPLETE GRID: {grid_runs[0]} of {grid_runs[1]} runs "
                            f"present.** Every verdict below is PROVISIONAL (decided on the "
                            f"runs present; the missing ones may change it) and the means "
                            f"cover only these runs. Run `psbench +experiment={name} "
                            f"scale={scale}` to complete the grid (stored runs are skipped)."))
    blocks += [("p", f"Experiment `{name}`, scale `{scale}`"
                    + (f" (image size {size} x {size}; the thesis used 512 x 512)" if size else "")
                    + "." + (f" {desc}" if desc else "")),
              ("p", f"Runs: {len(ok)} ok, {len(failed)} failed (of {len(rows_all)} stored at "
                    f"this scale). Back to [the index](index.html).")]
    if rows_all.empty:
        blocks.append(("p", f"**NO DATA**: the store holds no run of this experiment at this "
                            f"scale. Run `psbench +experiment={name} scale={scale}` first."))
    thesis = [v for v in verdicts if v.thesis]
    own = [v for v in verdicts if not v.thesis]
    blocks += [("h2", VERDICTS_HEADING), ("totals", _tally(thesis)),
               ("verdicts", thesis)]
    if own:
        blocks += [("h2", "psbench's own questions"),
                   ("p", "Questions the thesis does not ask (methods beyond it), decided with "
                         "the same rules; not counted in the verdict totals."),
                   ("own_verdicts", own)]
    if figs:
        blocks.append(("h2", "Figures"))
        for rel, stem in figs:
            blocks.append(("img", rel, f"{stem}: psbench at scale {scale}"))
    blocks += _comparison_blocks(name, cmp)
    blocks += [("h2", "What was run"),
               ("p", "What psbench averages: " + getattr(mod, "AVERAGES", "")),
               ("p", ("Deviations / caveats: " + notes) if notes else
                "Deviations / caveats: none beyond the image size stated above.")]
    if len(ok):
        blocks += [("h3", "Parameters of the ok runs"), ("table", _parameters(ok))]
    if len(failed):
        errs = failed["error"].fillna("(no message)").astype(str).str.slice(0, 200)
        counts = errs.value_counts()
        blocks += [("h3", "Failed runs"),
                   ("table", pd.DataFrame([{"runs": n, "error": msg}
                                           for msg, n in counts.items()][:10]))]
    text = T.grid_text(name)
    if text is not None:
        blocks += [("h3", "Experiment definition (grid YAML)"), ("pre", text)]
    return blocks


def _findings(names, verdicts_by) -> pd.DataFrame:
    order = {V.NOT_SUPPORTED: 0, V.SUPPORTED: 1, V.INCONCLUSIVE: 2}
    recs = []
    for name in names:
        vs = verdicts_by.get(name) or []
        if vs:
            v = vs[0]
            recs.append((order.get(v.status, 3), len(recs),
                         {"status": v.status, "experiment": Link(name, f"{name}.html"),
                          "claim": v.claim, "psbench's numbers": v.detail}))
    recs.sort(key=lambda r: r[:2])
    return pd.DataFrame([r[2] for r in recs],
                        columns=["status", "experiment", "claim", "psbench's numbers"])


#: summary keys of the verdict counts, by status
_KEYS = {V.SUPPORTED: "supported", V.NOT_SUPPORTED: "not_supported",
         V.INCONCLUSIVE: "inconclusive", V.PROVISIONAL: "provisional"}


def _records(summaries, kept, order=None) -> list:
    """One record per experiment (``name``, ``ok``, ``expected``, ``kept``, ``counts``:
    ``{status: n}``), built and kept alike, in ``order`` (default: the registered one)."""
    recs = [dict(name=s["experiment"], ok=int(s["ok"]), expected=s.get("expected"), kept=False,
                 counts={c: int(s.get(k) or 0) for c, k in _KEYS.items()}) for s in summaries]
    recs += [dict(name=n, ok=int(e.get("runs", 0)), expected=e.get("expected"), kept=True,
                  counts={c: int(e.get(c) or 0) for c in _KEYS}) for n, e in (kept or {}).items()]
    pos = {n: i for i, n in enumerate(order if order is not None else T.names())}
    return sorted(recs, key=lambda r: pos.get(r["name"], len(pos)))


def totals(summaries, kept=None) -> dict:
    """``{status: n}`` over the built summaries and the kept pages' entries
    (:func:`psbench.report.scales.kept`) whose experiments count (:func:`in_totals`)."""
    # experiments that re-decide other pages' claims (IN_TOTALS = False, e.g. the matrix of
    # readings) are listed but not counted again in the totals
    recs = [r for r in _records(summaries, kept) if in_totals(r["name"])]
    return {c: sum(r["counts"][c] for r in recs) for c in STATUSES}


def _ok_cell(r):
    if r["expected"] and r["ok"] < r["expected"]:
        return f"{r['ok']} of {r['expected']} (incomplete grid{'; kept' if r['kept'] else ''})"
    return f"{r['ok']} (kept)" if r["kept"] else r["ok"]


def index_blocks(*, scale, size_text, provenance, summaries, verdicts_by, messages,
                 empty, other_link, panels, deviations, kept=None, order=None) -> list:
    """Blocks of ``index`` for one scale.

    ``kept``: ``{experiment: entry}`` of the pages left from an earlier build
    (:func:`psbench.report.scales.kept`): rows of the verdict table (marked kept) and
    counted in the totals like built pages; ``verdicts_by`` holds their claims as their
    builds stated them (:func:`psbench.report.scales.kept_verdicts`). ``order``: the
    experiments' order (default: the registered one, :func:`psbench.report.tables.names`).
    """
    recs = _records(summaries, kept, order)
    all_v = [v for r in recs for v in verdicts_by.get(r["name"]) or []]
    tot = totals(summaries, kept)
    blocks = [("h1", f"psbench thesis reproduction report (scale: {scale})"),
              ("p", size_text + (f" {other_link}" if other_link else ""))]
    if empty:
        blocks.append(("p", f"**THE RESULTS STORE IS EMPTY**: no runs were found, so every "
                            f"table below is empty and every verdict INCONCLUSIVE. Run e.g. "
                            f"`psbench +experiment=table5_3 scale={scale}` first."))
    partial = [f"{r['name']} ({r['ok']} of {r['expected']} runs{', kept' if r['kept'] else ''})"
               for r in recs if r["expected"] and r["ok"] < r["expected"]]
    if partial:
        blocks.append(("p", f"**INCOMPLETE GRIDS: {', '.join(partial)}.** Their verdicts are "
                            f"PROVISIONAL (decided on the runs present) until their grids are "
                            f"complete."))
    blocks += [("h2", "Verdicts at a glance"),
               ("p", "Each page decides the thesis's qualitative conclusions on psbench's "
                     "numbers: SUPPORTED, NOT SUPPORTED, or INCONCLUSIVE (no data, or a gap "
                     "below its margin)."),
               ("totals", tot)]
    cols = ["experiment", "thesis item", "ok runs", V.SUPPORTED, V.NOT_SUPPORTED,
            V.INCONCLUSIVE] + ([V.PROVISIONAL] if tot.get(V.PROVISIONAL) else [])
    per = pd.DataFrame([{
        "experiment": Link(r["name"], f"{r['name']}.html"), "thesis item": T.title(r["name"]),
        "ok runs": _ok_cell(r), **{c: r["counts"][c] for c in cols[3:]}} for r in recs],
        columns=cols)
    if len(per):
        per.loc[len(per)] = ["total", "", sum(r["ok"] for r in recs)] + \
            [tot.get(c, 0) for c in cols[3:]]
    left = [r["name"] for r in recs if not in_totals(r["name"])]
    blocks.append(("table", per, "verdicts per experiment (click a name for its page)"
                   + (f"; the total leaves out {', '.join(left)}, which re-decides the "
                      "other pages' claims under alternative readings" if left else "")))
    if kept:
        blocks.append(("p", f"Pages kept from an earlier build ({len(kept)}): "
                            f"{', '.join(kept)}. This store holds no {scale}-scale run of "
                            f"them, so their pages were left as they were; their rows above "
                            f"(marked kept) and the totals use the runs and verdicts those "
                            f"pages report, from another store; so do their claims below, "
                            f"as their pages state them. `--force` replaces them."))
    blocks += [("h2", "Key findings"),
               ("p", "The main conclusion of each table and figure (the first claim on its "
                     "page) and what psbench's runs say about it; claims psbench does not "
                     "support come first. Every claim is listed under All verdicts below."),
               ("table", _findings([r["name"] for r in recs], verdicts_by))]
    if messages:
        blocks += [("h2", "Warnings"), ("list", messages)]
    if panels:
        blocks += [("h2", "Image panels"),
                   ("links", [("panels.html", "masks, NE maps, normals, WPS and a 3D height "
                                              "render of one small scene set (made by "
                                              "`psbench-report --panels`, not from the "
                                              "store)")])]
    blocks += [("h2", "Provenance and measured wall time"), ("p", provenance)]
    tab = pd.DataFrame([{
        "experiment": s["experiment"], "image size": s["size"] or "—", "ok": s["ok"],
        "failed": s["failed"], "run time sum (s)": f"{s['busy']:.1f}",
        "first run (UTC)": _ts(s["first"]), "last run (UTC)": _ts(s["last"]),
        "wall span (min)": f"{s['span'] / 60:.2f}"} for s in summaries])
    blocks.append(("table", tab))
    if kept:
        blocks.append(("p", f"The {len(kept)} kept page(s) were built from another store "
                            f"and are not in this table; their runs are stated on their own "
                            f"pages."))
    if deviations:
        blocks += [("h2", "Deviations from the thesis"),
                   ("table", pd.DataFrame(deviations, columns=["experiment", "deviation"]))]
    blocks += [("h2", "All verdicts"),
               ("table", pd.DataFrame([{"experiment": Link(v.experiment,
                                                           f"{v.experiment}.html"),
                                        "status": v.status, "claim": v.claim,
                                        "psbench's numbers": v.detail} for v in all_v],
                                      columns=["experiment", "status", "claim",
                                               "psbench's numbers"]))]
    return blocks
