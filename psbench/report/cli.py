"""``psbench-report``: rebuild ``reports/`` from the results store alone.

Usage::

    psbench-report [--results results] [--out reports] [--scale full|ci] [--panels]

Reads every row of the store (never solves), aggregates each registered experiment
(:mod:`psbench.experiments`, found through :mod:`psbench.registry`; the generic steps are
in :mod:`psbench.report.tables`), compares with the thesis's values, decides one verdict
per qualitative conclusion (:mod:`psbench.report.verdicts`), draws the figures and writes one
Markdown and one HTML page per experiment plus ``index.md`` / ``index.html`` with the
measured wall time of the runs and provenance. ``--panels`` additionally renders and
solves ONE small scene to draw the image panels of Figs. 5.15-5.17 (clearly labelled as
such; see :mod:`psbench.report.panels`). All files are written atomically; corrupt or
foreign Parquet files are named in a warning and skipped; an empty store gives a report
that says so.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from . import figures as F
from . import tables as T
from . import verdicts as V
from .aggregates import data_name
from .html import save_figure, write_atomic, write_page

MAX_PIVOT_COLS = 16


def _git_sha():
    try:
        here = Path(__file__).resolve().parent
        r = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True,
                           text=True, timeout=10)
        sha = r.stdout.strip() or None
        d = subprocess.run(["git", "-C", str(here), "status", "--porcelain",
                            "--untracked-files=no"], capture_output=True, text=True, timeout=20)
        return sha, bool(d.stdout.strip())
    except Exception:  # noqa: BLE001
        return None, None


def _num_sort(values):
    vals = list(dict.fromkeys(values))
    try:
        return sorted(vals, key=float)
    except (TypeError, ValueError):
        return vals


def _fmtv(x):
    if x is None or (isinstance(x, float) and np.isnan(x)):
        return None
    return f"{x:.4g}" if abs(x) < 1e4 else f"{x:.3e}"


def _cell(ps, th, df):
    a, b = _fmtv(ps), _fmtv(th)
    if a is None and b is None:
        return ""
    if b is None:
        return a
    if a is None:
        return f"— / {b}"
    return f"{a} / {b} ({df:+.3g})"


def pivot_part(cmp: pd.DataFrame, part: str) -> pd.DataFrame:
    """Wide table of one part: rows x columns, cells 'psbench / thesis (diff)'."""
    p = cmp[cmp["part"] == part]
    rows = list(dict.fromkeys(p["row"]))
    cols = list(dict.fromkeys(p["column"]))
    if all(_isnum(c) for c in cols):
        cols = _num_sort(cols)
    out = []
    for r in rows:
        rec = {"row": r}
        for c in cols:
            m = p[(p["row"] == r) & (p["column"] == c)]
            rec[c] = _cell(m["psbench"].iloc[0], m["thesis"].iloc[0], m["diff"].iloc[0]) \
                if len(m) else ""
        out.append(rec)
    return pd.DataFrame(out, columns=["row"] + cols)


def _isnum(x):
    try:
        float(x)
        return True
    except (TypeError, ValueError):
        return False


def _wall(rows: pd.DataFrame) -> dict:
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


def _pstr(v):
    if isinstance(v, float) and v == int(v) and abs(v) < 1e9:
        return str(int(v))
    return str(v)


def _averaged_over(rows):
    keys = ("surface", "data", "lights", "noise", "mask", "method", "weight", "model", "shadows",
            "size", "seed")
    out = []
    for k in keys:
        if k in rows and rows[k].notna().any():
            vals = _num_sort([_pstr(v) if k != "data" else data_name(v)
                              for v in rows[k].dropna().unique()])
            if len(vals) > 12:
                vals = vals[:12] + [f"... ({len(vals)} values)"]
            out.append(f"{k}: {', '.join(vals)}")
    return out


def build_experiment(name, df, out, scale, messages, results=None):
    """Write one experiment's page; returns (summary dict, verdicts)."""
    mod = T.experiment_module(name)
    rows_all = T.select(df, name, scale, status=None, results=results)
    ok = rows_all[rows_all["status"] == "ok"] if not rows_all.empty else rows_all
    failed = rows_all[rows_all["status"] != "ok"] if not rows_all.empty else rows_all
    agg = T.aggregate(name, ok)
    cmp = T.compare(name, agg)
    verdicts = V.verdicts(name, agg, ok)
    spec = T.grid(name, results)
    size = T.scale_size(name, scale, results)
    notes = getattr(mod, "NOTES", "")
    blocks = [("h1", T.title(name)),
              ("p", f"Experiment `{name}`, scale `{scale}`"
                    + (f" (image size {size} x {size}; the thesis used 512 x 512)" if size else "")
                    + f". {spec.get('description', '')}"),
              ("p", "What psbench averages: " + getattr(mod, "AVERAGES", "")),
              ("p", ("Deviations / caveats: " + notes) if notes else
                    "Deviations / caveats: none beyond the image size stated above."),
              ("p", f"Runs: {len(ok)} ok, {len(failed)} failed (of {len(rows_all)} stored at "
                    f"this scale).")]
    if len(ok):
        blocks += [("h3", "Parameters of the ok runs"), ("list", _averaged_over(ok))]
    if len(failed):
        errs = failed["error"].fillna("(no message)").astype(str).str.slice(0, 200)
        counts = errs.value_counts()
        blocks += [("h3", "Failed runs"),
                   ("list", [f"{n} run(s): {msg}" for msg, n in counts.items()][:10])]
    if rows_all.empty:
        blocks.append(("p", "NO DATA: the store holds no run of this experiment at this scale. "
                            f"Run `psbench +experiment={name} scale={scale}` first."))
    blocks += [("h2", "Verdicts on the thesis's conclusions"), ("verdicts", verdicts)]
    figs, errs = F.figures(name, agg)
    messages.extend(errs)
    if figs:
        blocks.append(("h2", "Figures"))
        for stem, fig in figs:
            save_figure(fig, Path(out) / "figures" / f"{stem}.png", dpi=F.DPI)
            blocks.append(("img", f"figures/{stem}.png", f"{stem}: psbench, scale {scale}"))
    blocks.append(("h2", "psbench vs thesis"))
    blocks.append(("p", "Cells: psbench / thesis (psbench - thesis); a lone number is psbench "
                        "(the thesis printed none); '— / x' means psbench has no value."))
    hidden = set(getattr(mod, "HIDDEN_PARTS", ()))
    for part in list(dict.fromkeys(cmp["part"])):
        if part in hidden:
            blocks.append(("p", f"Part '{part}' ({int((cmp['part'] == part).sum())} cells) is "
                                f"plotted above and listed in data/{name}.csv."))
            continue
        piv = pivot_part(cmp, part)
        if part:
            blocks.append(("h3", f"Part: {part}"))
        if piv.shape[1] - 1 > MAX_PIVOT_COLS:
            piv = cmp[cmp["part"] == part].drop(columns="part").head(80)
        blocks.append(("table", piv))
    text = T.grid_text(name)
    if text is not None:
        blocks += [("h2", "Experiment definition"), ("pre", text)]
    write_page(out, name, blocks, T.title(name))
    write_atomic(Path(out) / "data" / f"{name}.csv", cmp.to_csv(index=False))
    shas = sorted(set(rows_all["git_sha"].dropna())) if "git_sha" in rows_all else []
    summary = dict(experiment=name, **_wall(rows_all), size=size, shas=shas,
                   dirty=int(rows_all["git_dirty"].fillna(False).astype(bool).sum())
                   if "git_dirty" in rows_all else 0,
                   supported=sum(v.status == V.SUPPORTED for v in verdicts),
                   not_supported=sum(v.status == V.NOT_SUPPORTED for v in verdicts),
                   inconclusive=sum(v.status == V.INCONCLUSIVE for v in verdicts))
    return summary, verdicts


def build(results="results", out="reports", scale="full", panels=False, log=print,
          experiments=None) -> Path:
    """Rebuild the report folder; returns the path of ``index.html``.

    ``experiments`` restricts the pages to a subset of the registered experiments
    (:func:`psbench.report.tables.names`).
    """
    import psbench

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    df, messages = T.load_store(results)
    for m in messages:
        log(f"warning: {m}")
    summaries, all_verdicts = [], []
    names = [n for n in T.names() if experiments is None or n in experiments]
    for name in names:
        s, vs = build_experiment(name, df, out, scale, messages, results=results)
        summaries.append(s)
        all_verdicts.extend(vs)
    panel_files = []
    if panels:
        from .panels import build_panels

        panel_files = build_panels(out, log=log)
    elif (out / "panels").is_dir():
        panel_files = sorted(p.name for p in (out / "panels").glob("*.png"))
    sha, dirty = _git_sha()
    summ = pd.DataFrame(summaries)
    tot_busy = float(summ["busy"].sum()) if len(summ) else 0.0
    firsts = summ["first"].dropna() if len(summ) else pd.Series(dtype=object)
    lasts = summ["last"].dropna() if len(summ) else pd.Series(dtype=object)
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    blocks = [("h1", f"psbench thesis reproduction report (scale: {scale})"),
              ("p", f"Generated {now} from the results store '{results}' by psbench-report "
                    f"(no solving). psbench {psbench.__version__}, git {sha or 'unknown'}"
                    f"{' (dirty tree)' if dirty else ''}.")]
    if df.empty:
        blocks.append(("p", "THE RESULTS STORE IS EMPTY: no runs were found, so every table "
                            "below is empty and every verdict INCONCLUSIVE. Run e.g. "
                            "`psbench +experiment=table5_3 scale=" + scale + "` first."))
    if messages:
        blocks += [("h2", "Warnings"), ("list", messages)]
    if len(df):
        shas = sorted({x for s in summaries for x in s["shas"]})
        dirty_rows = sum(s["dirty"] for s in summaries)
        n_rows = sum(s["n"] for s in summaries)
        vers = df["psbench_version"].dropna().unique() if "psbench_version" in df else []
        blocks.append(("p", f"Store: {len(df)} rows in total (all scales and sweeps), {n_rows} "
                            f"of them reported here; those were written by psbench "
                            f"{', '.join(map(str, vers)) or '?'} at git "
                            f"{', '.join(s[:10] for s in shas) or '?'} ({dirty_rows} from a tree "
                            f"with uncommitted changes: others were editing concurrently)."))
    blocks.append(("h2", "Measured wall time"))
    span = (max(lasts) - min(firsts)).total_seconds() if len(firsts) and len(lasts) else 0.0
    blocks.append(("p", f"Sum of the per-run times (render + solve) over all experiments at this "
                        f"scale: {tot_busy:.1f} s; first run {_ts(min(firsts) if len(firsts) else None)}"
                        f", last run {_ts(max(lasts) if len(lasts) else None)} UTC (span "
                        f"{span / 60:.1f} min, includes any pauses between experiments)."))
    tab = pd.DataFrame([{
        "experiment": s["experiment"], "size": s["size"] or "", "ok": s["ok"],
        "failed": s["failed"], "run time sum (s)": round(s["busy"], 1),
        "first utc": _ts(s["first"]), "last utc": _ts(s["last"]),
        "wall span (min)": round(s["span"] / 60, 2), "SUPPORTED": s["supported"],
        "NOT SUPPORTED": s["not_supported"], "INCONCLUSIVE": s["inconclusive"]}
        for s in summaries])
    blocks.append(("table", tab))
    blocks += [("h2", "Deviations from the thesis (chosen to fit the time budget or the data)"),
               ("list", [f"{n}: {getattr(T.experiment_module(n), 'NOTES', '')}" for n in names
                         if getattr(T.experiment_module(n), "NOTES", "")])]
    blocks += [("h2", "Pages"),
               ("links", [(f"{n}.html", f"{T.title(n)} ({n})") for n in names])]
    other = "ci" if scale == "full" else None
    if other and (out / other / "index.html").is_file():
        blocks += [("h2", "Other scale"),
                   ("links", [(f"{other}/index.html", f"the same report on the {other}-scale runs "
                                                      f"(small images, fixed seeds; the CI gate's "
                                                      f"data)")])]
    if panel_files:
        blocks += [("h2", "Image panels (one small scene rendered and solved by "
                          "psbench-report --panels, not from the store)"),
                   ("links", [("panels.html", "Figs. 5.15-5.17 style panels, normals, NE maps, "
                                              "3D render")])]
    blocks += [("h2", "All verdicts")]
    blocks.append(("table", pd.DataFrame([v.as_dict() for v in all_verdicts],
                                         columns=["experiment", "status", "claim", "detail"])))
    write_page(out, "index", blocks, "psbench report")
    log(f"report written to {out / 'index.html'} ({len(df)} store rows, "
        f"{sum(v.status == V.SUPPORTED for v in all_verdicts)} SUPPORTED, "
        f"{sum(v.status == V.NOT_SUPPORTED for v in all_verdicts)} NOT SUPPORTED, "
        f"{sum(v.status == V.INCONCLUSIVE for v in all_verdicts)} INCONCLUSIVE)")
    return out / "index.html"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="psbench-report", description=__doc__.split("\n\n")[0])
    ap.add_argument("--results", default=None,
                    help="results store root (default $PSBENCH_RESULTS or results)")
    ap.add_argument("--out", default="reports", help="report folder (default reports)")
    ap.add_argument("--scale", default="full", choices=("full", "ci"),
                    help="which scale's rows to report (default full)")
    ap.add_argument("--panels", action="store_true",
                    help="also render+solve one small scene for the image panels")
    a = ap.parse_args(argv)
    from psbench.harness.store import default_root

    build(default_root(a.results), a.out, a.scale, panels=a.panels)
    return 0


if __name__ == "__main__":
    sys.exit(main())
