"""``psbench-report``: rebuild the reports from the results store alone.

Usage::

    psbench-report [--results results] [--out reports] [--scale auto|full|ci] [--panels]
                   [--force]

Reads every row of the store (never solves), aggregates each registered experiment
(:mod:`psbench.experiments`, found through :mod:`psbench.registry`; the generic steps are
in :mod:`psbench.report.tables`), compares with the thesis's values, decides one verdict
per qualitative conclusion (:mod:`psbench.report.verdicts`), draws the figures and writes
one Markdown and one HTML page per experiment plus ``index.md`` / ``index.html`` (verdict
totals and key findings first) and ``report.json``.

Scales: the full-scale report goes to ``<out>/``, the ci-scale one to ``<out>/ci/``. By
default (``--scale auto``) every scale the store holds is reported; a report that holds
data is never replaced by an emptier one: the pages of experiments the store lacks at
that scale are kept as they are (still rows of the index, marked kept, and counted in
its totals), and a store with no run at that scale, fewer runs than a page reports, or a
folder of another scale stops the command with a one-line message and exit status 2,
changing nothing (``--force`` overrides; see :mod:`psbench.report.scales`). A page
whose grid is incomplete says so at the top (runs present / expected) and its verdicts
are PROVISIONAL. ``--panels`` additionally renders and solves ONE small scene set for the
image panels (labelled as such; :mod:`psbench.report.panels`). All files are written
atomically; corrupt or foreign Parquet files are named in a warning and skipped.
"""
from __future__ import annotations

import argparse
import datetime as _dt
import sys
from pathlib import Path

import pandas as pd

from .._shared.provenance import git_state
from . import figures as F
from . import pages as G
from . import scales as S
from . import tables as T
from . import verdicts as V
from ..io.html import save_figure, write_atomic, write_page

__all__ = ["build", "build_all", "main"]


def _build_experiment(name, rows_all, out, scale, messages, results):
    """Write one experiment's page, figures and CSV; returns (summary, verdicts)."""
    ok = rows_all[rows_all["status"] == "ok"] if not rows_all.empty else rows_all
    agg = T.aggregate(name, ok)
    cmp = T.compare(name, agg)
    verdicts = V.verdicts(name, agg, ok)
    grid_runs = T.completeness(name, scale, rows_all, results)
    if grid_runs and grid_runs[0] < grid_runs[1]:   # missing runs may change any verdict
        verdicts = V.provisional(verdicts, *grid_runs)
    thesis = [v for v in verdicts if v.thesis]     # the totals count thesis claims only
    size = T.scale_size(name, scale, results)
    figs, errs = F.figures(name, agg, rows=ok)
    messages.extend(errs)
    rel = []
    for stem, fig in figs:
        save_figure(fig, Path(out) / "figures" / f"{stem}.png", dpi=F.DPI)
        rel.append((f"figures/{stem}.png", stem))
    blocks = G.experiment_blocks(name, scale, size, rows_all, agg, cmp, verdicts, rel,
                                 results=results, grid_runs=grid_runs)
    write_page(out, name, blocks, T.title(name))
    write_atomic(Path(out) / "data" / f"{name}.csv", cmp.to_csv(index=False))
    shas = sorted(set(rows_all["git_sha"].dropna())) if "git_sha" in rows_all else []
    summary = dict(experiment=name, **G.wall(rows_all), size=size, shas=shas,
                   dirty=int(rows_all["git_dirty"].fillna(False).astype(bool).sum())
                   if "git_dirty" in rows_all else 0,
                   supported=sum(v.status == V.SUPPORTED for v in thesis),
                   not_supported=sum(v.status == V.NOT_SUPPORTED for v in thesis),
                   inconclusive=sum(v.status == V.INCONCLUSIVE for v in thesis),
                   provisional=sum(v.status == V.PROVISIONAL for v in thesis),
                   expected=grid_runs[1] if grid_runs else None,
                   own=len(verdicts) - len(thesis))
    return summary, thesis


def _selections(df, scale, names, results):
    return {n: T.select(df, n, scale, status=None, results=results) for n in names}


def _ok_runs(sel) -> dict:
    return {n: int((r["status"] == "ok").sum()) if len(r) else 0 for n, r in sel.items()}


def build(results="results", out="reports", scale="full", panels=False, log=print,
          experiments=None, force=False, _store=None, _warned=False,
          _checked=False) -> Path:
    """Rebuild the ``scale`` report in the folder ``out``; returns ``out/index.html``.

    Raises :class:`psbench.report.scales.ReportRefused` before writing anything when
    ``out`` holds a report of another scale with data, or pages with data the store
    lacks at this scale (``force`` overrides). ``experiments`` restricts the pages to a
    subset of the registered experiments (:func:`psbench.report.tables.names`).
    """
    out = Path(out)
    df, messages = _store if _store is not None else T.load_store(results)
    messages = list(messages)
    names = [n for n in T.names() if experiments is None or n in experiments]
    sel = _selections(df, scale, names, results)
    if not _warned:
        _warn(messages)
    if not _checked:
        S.check(out, scale, _ok_runs(sel), results, force=force)
    # pages holding runs this store lacks stay as they are (never replaced by NO DATA)
    kept = {} if force else S.kept(out, _ok_runs(sel))
    out.mkdir(parents=True, exist_ok=True)
    summaries, verdicts_by = [], {}
    for name in (n for n in names if n not in kept):
        s, vs = _build_experiment(name, sel[name], out, scale, messages, results)
        s["in_totals"] = G.in_totals(name)
        summaries.append(s)
        verdicts_by[name] = vs
    for name, entry in kept.items():      # a kept page's claims, as its build stated them
        verdicts_by[name] = S.kept_verdicts(out, name, entry)
    panel_files = []
    if panels:
        from .panels import build_panels

        panel_files = build_panels(out, log=log)
    elif (out / "panels").is_dir():
        panel_files = sorted(p.name for p in (out / "panels").glob("*.png"))
    now = _dt.datetime.now(_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")
    blocks = G.index_blocks(
        scale=scale, size_text=_size_text(summaries, scale, kept),
        provenance=_provenance(df, summaries, results, now),
        summaries=summaries, verdicts_by=verdicts_by, messages=messages, empty=df.empty,
        other_link=_other_link(out, scale), panels=bool(panel_files), kept=kept, order=names,
        deviations=[(n, getattr(T.experiment_module(n), "NOTES", "")) for n in names
                    if getattr(T.experiment_module(n), "NOTES", "")])
    write_page(out, "index", blocks, f"psbench report ({scale})")
    write_atomic(out / S.MANIFEST, S.manifest(scale, G.display_path(results), summaries, now,
                                              kept, order=names, verdicts=verdicts_by))
    tot = G.totals(summaries, kept)           # the index's totals, kept pages included
    log(f"{scale}-scale report written to {out / 'index.html'} ({len(df)} store rows; "
        f"{tot[V.SUPPORTED]} SUPPORTED, {tot[V.NOT_SUPPORTED]} NOT SUPPORTED, "
        f"{tot[V.INCONCLUSIVE]} INCONCLUSIVE"
        + (f", {tot[V.PROVISIONAL]} PROVISIONAL" if tot[V.PROVISIONAL] else "") + ")"
        + (f"; kept the pages of {', '.join(kept)} (runs this store lacks)" if kept else ""))
    return out / "index.html"


def _warn(messages):
    for m in messages:              # store warnings: diagnostics, on stderr
        print(f"warning: {m}", file=sys.stderr, flush=True)


def _size_text(summaries, scale, kept=None) -> str:
    # kept pages' sizes too (their entries', :func:`scales.kept`): the index covers them
    sizes = sorted({int(s["size"]) for s in summaries if s["size"]}
                   | {int(e["size"]) for e in (kept or {}).values() if e.get("size")})
    sz = ", ".join(f"{x} x {x}" for x in sizes) or "no images"
    return (f"Thesis tables and figures re-run by psbench at the `{scale}` scale (image sizes "
            f"{sz}; the thesis used 512 x 512), compared with the thesis's printed values.")


def _other_link(out, scale) -> str:
    if scale == "full" and (out / "ci" / "index.html").is_file():
        return "The same report on the ci-scale runs (small images, the CI gate's data): " \
               "[ci/index.html](ci/index.html)."
    if scale == "ci" and out.name == "ci" and (out.parent / "index.html").is_file():
        return "The full-scale report: [../index.html](../index.html)."
    return ""


def _provenance(df, summaries, results, now) -> str:
    import psbench

    sha, dirty = git_state()
    text = (f"Generated {now} from the results store `{G.display_path(results)}` by "
            f"psbench-report (no solving); psbench {psbench.__version__}, git "
            f"{(sha or 'unknown')[:10]}{' (uncommitted changes)' if dirty else ''}.")
    if len(df):
        shas = sorted({x for s in summaries for x in s["shas"]})
        vers = df["psbench_version"].dropna().unique() if "psbench_version" in df else []
        n_rows = sum(s["n"] for s in summaries)
        dirty_rows = sum(s["dirty"] for s in summaries)
        firsts = [s["first"] for s in summaries if s["first"] is not None]
        lasts = [s["last"] for s in summaries if s["last"] is not None]
        span = (max(lasts) - min(firsts)).total_seconds() / 60 if firsts and lasts else 0.0
        busy = sum(s["busy"] for s in summaries)
        text += (f" The store holds {len(df)} rows (all scales and sweeps); {n_rows} are "
                 f"reported here, written by psbench {', '.join(map(str, vers)) or '?'} at "
                 f"git {', '.join(s[:10] for s in shas) or '?'} ({dirty_rows} from a tree "
                 f"with uncommitted changes). Sum of per-run times (render + solve): "
                 f"{busy:.1f} s; runs span {span:.1f} min of wall time (including any pauses "
                 f"between experiments).")
    return text


def build_all(results="results", out="reports", scale="auto", panels=False, log=print,
              force=False) -> list[Path]:
    """Build the report of every scale the store holds (``scale="auto"``) or of one scale:
    full into ``out``, ci into ``out/ci``. Every target is checked before anything is
    written (:func:`psbench.report.scales.check`); returns the index paths."""
    store = T.load_store(results)
    _warn(store[1])
    if scale == "auto":
        held = S.held(store[0], results)
        targets = [s for s in S.SCALES if held[s]] or ["full"]
        for s in S.SCALES:
            if s not in targets and S.existing(S.folder(out, s)):
                log(f"{s} scale: the store holds no {s}-scale runs; "
                    f"{S.folder(out, s)} is left as it is")
    else:
        targets = [scale]
    names = T.names()
    for s in targets:
        S.check(S.folder(out, s), s, _ok_runs(_selections(store[0], s, names, results)),
                results, force=force)
    with_panels = "full" if "full" in targets else targets[0]
    # ci first, so that the full index can link to it
    order = sorted(targets, key=lambda s: s == "full")
    return [build(results, S.folder(out, s), s, panels=panels and s == with_panels, log=log,
                  force=force, _store=store, _warned=True, _checked=True) for s in order]


def main(argv=None) -> int:
    from .._shared.warn import install

    install()                           # warnings as one psbench line each
    ap = argparse.ArgumentParser(prog="psbench-report",
                                 description="Rebuild the thesis reports from the results "
                                             "store alone (never solves).",
                                 epilog="Full-scale report in OUT/, ci-scale report in OUT/ci/; "
                                        "pages of experiments the store lacks are kept, and "
                                        "a report holding data is never replaced by an "
                                        "emptier one (exit 2) unless --force.")
    ap.add_argument("--results", default=None,
                    help="results store root (default $PSBENCH_RESULTS or results)")
    ap.add_argument("--out", default="reports", help="report root folder (default reports)")
    ap.add_argument("--scale", default="auto", choices=("auto",) + S.SCALES,
                    help="which scale to report (default auto: every scale the store holds; "
                         "full goes to OUT, ci to OUT/ci)")
    ap.add_argument("--panels", action="store_true",
                    help="also render+solve one small scene set for the image panels")
    ap.add_argument("--force", action="store_true",
                    help="replace a report even if it holds data the store lacks (its "
                         "kept pages become NO DATA pages)")
    a = ap.parse_args(argv)
    from psbench.harness.store import default_root

    try:
        build_all(default_root(a.results), a.out, a.scale, panels=a.panels, force=a.force)
    except S.ReportRefused as exc:
        print(str(exc), file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
