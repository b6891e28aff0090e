"""``psbench-results``: inspect and maintain the Parquet results store.

::

    psbench-results ls [--root results]              # rows per sweep: ok / failed, last run
    psbench-results summary [--root R] [--experiment E] [--by mask,noise]
    psbench-results compact [--root results] [--sweep S]
    psbench-results verify [--root results]          # unreadable files, duplicates, schema

The root defaults to ``$PSBENCH_RESULTS`` or ``results`` in the current directory.
"""
from __future__ import annotations

import argparse
import sys
import warnings

__all__ = ["main"]


def _root(args):
    from .store import default_root

    return default_root(args.root)


def _ls(args):
    from .store import read_store

    df = read_store(_root(args), sweep=args.sweep)
    if df.empty:
        print(f"no runs stored under {_root(args)}")
        return 0
    g = df.groupby("sweep", dropna=False)
    out = g.agg(rows=("run_id", "size"), ok=("status", lambda s: int((s == "ok").sum())),
                failed=("status", lambda s: int((s != "ok").sum())), last=("utc", "max"))
    print(out.to_string())
    return 0


def _summary(args):
    import pandas as pd

    from .store import read_store

    df = read_store(_root(args), experiment=args.experiment, sweep=args.sweep)
    if df.empty:
        print("no runs")
        return 0
    by = [c for c in (args.by or "sweep,mask").split(",") if c]
    bad = [c for c in by if c not in df.columns]
    if bad:
        print(f"psbench-results: error: unknown column(s) {bad}", file=sys.stderr)
        return 2
    ok = df[df["status"] == "ok"]
    cols = ["ne_mean", "ie_rel", "qf_total", "t_solve"]
    with pd.option_context("display.width", 200, "display.max_rows", 500):
        print(ok.groupby(by, dropna=False)[cols].mean().round(3).assign(
            runs=ok.groupby(by, dropna=False).size()).to_string())
    nf = int((df["status"] != "ok").sum())
    if nf:
        print(f"{nf} failed run(s); e.g.: {df.loc[df['status'] != 'ok', 'error'].iloc[0]}")
    return 0


def _compact(args):
    from .store import compact

    out = compact(_root(args), sweep=args.sweep, verbose=True)
    if not out:
        print("nothing to compact")
    return 0


def _verify(args):
    from pathlib import Path

    from .schema import SCHEMA_VERSION
    from .store import COMPACT_NAME, StoreWarning, _files, _read_file, dead_temp, temp_files

    root = _root(args)
    comp, runs = _files(root, args.sweep)
    problems = 0
    seen = {}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", StoreWarning)
        for p in comp + runs:
            t = _read_file(p)            # reads every page, verifying its checksum
            if t is None:
                continue
            versions = set(t.column("schema_version").to_pylist())
            if versions - {SCHEMA_VERSION}:
                print(f"{p}: schema_version {sorted(versions, key=str)} (current {SCHEMA_VERSION})")
            for s, r in zip(t.column("sweep").to_pylist(), t.column("run_id").to_pylist()):
                seen.setdefault((s, r), []).append(p)
            if p in runs and (t.num_rows != 1 or Path(p).stem != t.column("run_id")[0].as_py()):
                print(f"{p}: per-run file holds {t.num_rows} rows / run_id mismatch")
                problems += 1
            if p.name == COMPACT_NAME and p.parent.name != t.column("sweep")[0].as_py():
                print(f"{p}: holds rows of sweep {t.column('sweep')[0].as_py()!r}")
                problems += 1
    for w in caught:
        print(str(w.message))
        problems += 1
    dups = {k: v for k, v in seen.items() if len(v) > 1}
    for (s, r), files in dups.items():
        print(f"run {s}/{r} stored {len(files)} times ({', '.join(map(str, files))}); readers "
              f"keep the latest; compact merges")
    tmp = temp_files(root)
    dead = [p for p in tmp if dead_temp(p)]
    for p in dead:
        print(f"{p}: temporary file left by a writer that no longer runs (compact removes it)")
    problems += len(dead)
    if len(tmp) > len(dead):
        print(f"{len(tmp) - len(dead)} temporary file(s) of writers that may still be running")
    print(f"{len(comp) + len(runs)} files, {len(seen)} runs, {problems} problem(s)")
    return 1 if problems else 0


def main(args=None):
    """Console entry point ``psbench-results``."""
    ap = argparse.ArgumentParser(prog="psbench-results", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name, helptext in (("ls", "rows per sweep"), ("summary", "mean metrics per group"),
                           ("compact", "merge per-run files into one file per sweep"),
                           ("verify", "check files, duplicates and schema versions")):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("--root", default=None, help="store root (default $PSBENCH_RESULTS or results)")
        p.add_argument("--sweep", default=None, help="only this sweep / experiment folder")
        if name == "summary":
            p.add_argument("--experiment", default=None)
            p.add_argument("--by", default=None, help="comma-separated columns (default sweep,mask)")
    args = ap.parse_args(args)
    from .._shared.warn import install

    install()                           # store warnings as one psbench line each
    fn = {"ls": _ls, "summary": _summary, "compact": _compact, "verify": _verify}[args.cmd]
    try:
        return fn(args)
    except (ValueError, OSError) as exc:
        print(f"psbench-results: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
