"""CI regression gate on the CI-scale thesis experiments.

::

    python -m psbench.report.gate check  [--results DIR] [--baselines DIR] [--only a,b] [-v]
    python -m psbench.report.gate update [--results DIR] [--baselines DIR] [--only a,b]

The gate runs nothing itself. It reads the store, keeps each gated experiment's
``scale=ci`` rows, aggregates them exactly like the report
(:func:`psbench.report.tables.aggregate`: e.g. mean NE / QF / time per mask for
table5_3, mean NE per configuration for table5_4 and table5_5) and compares every cell
with the committed baseline ``results/baselines/<experiment>.csv`` under the tolerances
of ``results/baselines/tolerances.yaml``. The gated experiments are the registered ones
whose module sets ``GATED = True`` (:func:`gated`); each cell's tolerance class comes
from the module's ``cell_kind(part, column)`` (default ``ne``):

- angles (NE, deg), condition values and QF: absolute tolerance;
- intensity errors and percentages: relative tolerance;
- timings: only a loose one-sided check (current <= ratio x baseline + floor seconds).

A baseline cell missing from the current results fails (a mask or layout stopped
producing rows); new cells are listed but do not fail. ``check`` prints a readable diff
table and exits 1 on any failure (2 when a baseline file is missing). ``update``
rewrites the baselines from the current results; it is the only way they change.
"""
from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import pandas as pd

from . import tables as T
from .._shared.deprecation import renamed_names
from ..io.html import write_atomic

DEFAULT_TOLERANCES = {
    "ne": {"abs": 0.3},          # degrees
    "cond": {"abs": 1e-3},
    "qf": {"abs": 0.03},
    "ie": {"rel": 0.05},
    "percent": {"abs": 3.0},     # percentage points (improvements, IE % of None)
    "time": {"ratio": 5.0, "floor": 0.05},
    "threshold": {"abs": 1e-9},
    "ratio": {"abs": 1.0},
}


def gated() -> tuple[str, ...]:
    """Experiments the CI gate checks (``GATED = True`` in their module), in report order;
    each is run with ``psbench +experiment=<name> scale=ci``."""
    return tuple(n for n in T.names() if getattr(T.experiment_module(n), "GATED", False))


def cell_kind(experiment: str, part: str, column: str) -> str:
    """Which kind (tolerance class) a cell belongs to: the module's ``cell_kind``
    (formerly ``metric_kind``)."""
    fn = getattr(T.experiment_module(experiment), "cell_kind", None)
    return str(fn(part, column)) if fn is not None else "ne"


def default_baselines() -> Path:
    return Path("results") / "baselines"


def load_tolerances(baselines: Path) -> dict:
    """Tolerances: defaults, overridden by ``tolerances.yaml`` (``default:`` per kind and
    ``experiments: {name: {kind: {...}}}``)."""
    import yaml

    tol = {"default": {k: dict(v) for k, v in DEFAULT_TOLERANCES.items()}, "experiments": {}}
    path = Path(baselines) / "tolerances.yaml"
    if path.is_file():
        doc = yaml.safe_load(path.read_text()) or {}
        for k, v in (doc.get("default") or {}).items():
            tol["default"].setdefault(k, {}).update(v or {})
        for e, kinds in (doc.get("experiments") or {}).items():
            tol["experiments"][e] = {k: dict(v or {}) for k, v in (kinds or {}).items()}
    return tol


def _tol_for(tol, experiment, kind):
    t = dict(tol["default"].get(kind, {}))
    t.update(tol["experiments"].get(experiment, {}).get(kind, {}))
    return t


def current_tables(results, experiments=None) -> dict:
    """``{experiment: long aggregate}`` of the CI-scale ok rows in the store."""
    experiments = gated() if experiments is None else experiments
    df, msgs = T.load_store(results)
    for m in msgs:
        print(f"warning: {m}", file=sys.stderr)
    return {e: T.aggregate(e, T.select(df, e, "ci", results=results)) for e in experiments}


def compare(experiment, base: pd.DataFrame, cur: pd.DataFrame, tol) -> pd.DataFrame:
    """Cell-by-cell comparison: columns experiment, key, kind, baseline, current, diff,
    limit, status (ok / FAIL / missing / new)."""
    key = ["part", "row", "column"]
    b = base[key + ["value"]].rename(columns={"value": "baseline"})
    c = cur[key + ["value"]].rename(columns={"value": "current"}) if not cur.empty else \
        pd.DataFrame(columns=key + ["current"])
    for f in (b, c):
        for k in key:
            f[k] = f[k].fillna("").astype(str)
    m = pd.merge(b, c, on=key, how="outer")
    recs = []
    for r in m.itertuples(index=False):
        kind = cell_kind(experiment, r.part, r.column)
        t = _tol_for(tol, experiment, kind)
        bv, cv = _num(r.baseline), _num(r.current)
        name = "/".join(x for x in (r.part, r.row, r.column) if x)
        if bv is None and cv is None:
            continue
        if bv is None:
            recs.append((experiment, name, kind, None, cv, None, "", "new"))
            continue
        if cv is None:
            recs.append((experiment, name, kind, bv, None, None, "", "missing"))
            continue
        diff = cv - bv
        if "ratio" in t:
            lim = t["ratio"] * bv + t.get("floor", 0.0)
            ok = cv <= lim
            limit = f"<= {lim:.3g}"
        elif "rel" in t:
            lim = t["rel"] * abs(bv) + t.get("abs", 0.0)
            ok = abs(diff) <= lim
            limit = f"+-{lim:.3g}"
        else:
            lim = t.get("abs", 0.0)
            ok = abs(diff) <= lim + 1e-12
            limit = f"+-{lim:.3g}"
        recs.append((experiment, name, kind, bv, cv, diff, limit, "ok" if ok else "FAIL"))
    return pd.DataFrame(recs, columns=["experiment", "key", "kind", "baseline", "current", "diff",
                                       "limit", "status"])


def _num(x):
    try:
        f = float(x)
    except (TypeError, ValueError):
        return None
    return None if math.isnan(f) else f


def _fmt_table(df: pd.DataFrame) -> str:
    if df.empty:
        return "(nothing)"

    def f(v):
        if v is None or (isinstance(v, float) and math.isnan(v)):
            return "-"
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    cols = list(df.columns)
    cells = [[f(v) for v in row] for row in df.itertuples(index=False)]
    w = [max(len(c), *(len(r[i]) for r in cells)) for i, c in enumerate(cols)]
    lines = ["  ".join(c.ljust(w[i]) for i, c in enumerate(cols)),
             "  ".join("-" * w[i] for i in range(len(cols)))]
    lines += ["  ".join(r[i].ljust(w[i]) for i in range(len(cols))) for r in cells]
    return "\n".join(lines)


def check(results=None, baselines=None, experiments=None, verbose=False, out=print) -> int:
    """Compare current CI aggregates with the baselines; returns the exit code."""
    experiments = gated() if experiments is None else experiments
    baselines = Path(baselines) if baselines is not None else default_baselines()
    tol = load_tolerances(baselines)
    cur = current_tables(results, experiments)
    frames, missing_files = [], []
    for e in experiments:
        path = baselines / f"{e}.csv"
        if not path.is_file():
            missing_files.append(str(path))
            continue
        base = pd.read_csv(path, dtype={"part": str, "row": str, "column": str},
                           keep_default_na=False, na_values=[""])
        frames.append(compare(e, base, cur[e], tol))
    res = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame(
        columns=["experiment", "key", "kind", "baseline", "current", "diff", "limit", "status"])
    bad = res[res["status"].isin(["FAIL", "missing"])]
    new = res[res["status"] == "new"]
    out(f"psbench gate: {len(res)} cells in {len(frames)} experiment(s); "
        f"{int((res['status'] == 'ok').sum())} ok, {int((res['status'] == 'FAIL').sum())} FAIL, "
        f"{int((res['status'] == 'missing').sum())} missing, {len(new)} new")
    for e in experiments:
        r = res[res["experiment"] == e]
        if len(r):
            out(f"  {e}: {int((r['status'] == 'ok').sum())}/{len(r)} ok")
    if verbose:
        out(_fmt_table(res))
    elif len(bad):
        out("failures:")
        out(_fmt_table(bad))
    if len(new) and verbose:
        out(f"{len(new)} new cell(s) without baseline (not failing)")
    if missing_files:
        out("missing baseline files (create them with `python -m psbench.report.gate update`): "
            + ", ".join(missing_files))
        return 2
    if len(bad):
        out("GATE FAILED")
        return 1
    out("GATE PASSED")
    return 0


def update(results=None, baselines=None, experiments=None, out=print) -> int:
    """Rewrite ``<baselines>/<experiment>.csv`` from the current CI rows."""
    experiments = gated() if experiments is None else experiments
    baselines = Path(baselines) if baselines is not None else default_baselines()
    cur = current_tables(results, experiments)
    empty = [e for e in experiments if cur[e].empty]
    if empty:
        out(f"refusing to update: no ok ci rows for {', '.join(empty)}; run "
            + "; ".join(f"psbench +experiment={e} scale=ci" for e in empty))
        return 1
    for e in experiments:
        df = cur[e][["part", "row", "column", "value", "n"]]
        write_atomic(baselines / f"{e}.csv", df.to_csv(index=False, float_format="%.6g"))
        out(f"wrote {baselines / f'{e}.csv'} ({len(df)} cells)")
    if not (baselines / "tolerances.yaml").is_file():
        import yaml

        write_atomic(baselines / "tolerances.yaml",
                     yaml.safe_dump({"default": DEFAULT_TOLERANCES}, sort_keys=False))
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m psbench.report.gate",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("command", choices=("check", "update"))
    ap.add_argument("--results", default=None, help="store root (default $PSBENCH_RESULTS or "
                                                    "results)")
    ap.add_argument("--baselines", default=None, help="baseline folder (default "
                                                      "results/baselines)")
    ap.add_argument("--only", default=None, help="comma-separated experiments (default: the "
                                                 "gated ones, GATED = True in their module)")
    ap.add_argument("-v", "--verbose", action="store_true", help="print every cell")
    a = ap.parse_args(argv)
    exps = gated()
    if a.only:
        exps = tuple(x.strip() for x in a.only.split(",") if x.strip())
        unknown = [x for x in exps if x not in T.names()]
        if unknown:
            ap.error(f"unknown experiment(s) {unknown}; valid: {', '.join(T.names())}")
    from psbench.harness.store import default_root

    results = default_root(a.results)
    if a.command == "check":
        return check(results, a.baselines, exps, verbose=a.verbose)
    return update(results, a.baselines, exps)


__getattr__ = renamed_names(globals(), {"metric_kind": "cell_kind"})


if __name__ == "__main__":
    sys.exit(main())
