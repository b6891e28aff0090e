"""From the results store to each experiment's aggregate and its comparison with the thesis.

Experiments are found through the registry (:func:`psbench.registry.experiments`): each
is one module with its grid YAML beside it (the contract is in
:mod:`psbench.experiments`). This module holds the generic steps every report page and
the CI gate share:

- :func:`names` / :func:`experiment_module` / :func:`title`: the registered experiments,
  in report order (thesis tables, then figures, then any other);
- :func:`load_store`, :func:`select`: one experiment's rows at one scale;
- :func:`aggregate`: the module's long-format aggregate (columns ``experiment, part, row,
  column, value, n``; see :mod:`psbench.report.aggregates`);
- :func:`thesis_frame`, :func:`compare`: the thesis's values of the same cells beside
  psbench's.
"""
from __future__ import annotations

import copy
import functools
import os
import re
import warnings
from pathlib import Path

import pandas as pd

from .aggregates import LONG_COLUMNS, long_frame

__all__ = ["names", "experiment_module", "title", "grid", "grid_text", "scale_size",
           "load_store", "expected_run_ids", "select", "aggregate", "thesis_frame", "compare"]

_KIND_ORDER = {"table": 0, "fig": 1}


def _order(name: str):
    """Report order: thesis tables, then figures, by number; then anything else by name."""
    m = re.match(r"([a-z]+)(\d.*)?$", name)
    kind = _KIND_ORDER.get(m.group(1), 2) if m else 2
    nums = tuple(int(x) for x in re.findall(r"\d+", name)) if kind < 2 else ()
    return kind, nums, name


def names() -> list[str]:
    """Registered experiment names in report order."""
    from psbench import registry

    return sorted(registry.experiments(), key=_order)


def experiment_module(name: str):
    """The module of a registered experiment (None when ``name`` is not registered)."""
    from psbench import registry
    from psbench._shared.checks import PsbenchError

    try:
        return registry.get("experiments", name).module
    except PsbenchError:
        return None


def title(name: str) -> str:
    """The experiment's ``TITLE`` (its name when it has none)."""
    return getattr(experiment_module(name), "TITLE", None) or name


def _cache_key(name, results):
    """What a resolved grid depends on: the experiment, the store folder, the grid file's
    modification time and the environment its interpolations may read."""
    from psbench import registry
    from psbench._shared.checks import PsbenchError

    try:
        path = registry.get("experiments", name).grid
        mtime = path.stat().st_mtime_ns if path is not None and path.is_file() else None
    except (PsbenchError, OSError):
        path, mtime = None, None
    env = tuple(sorted((k, v) for k, v in os.environ.items() if k.startswith("PSBENCH")))
    # a grid that never names the store resolves the same for every store: one cache entry
    store = str(results) if _names_store(str(path), mtime) else "None"
    return name, store, str(path), mtime, env


@functools.lru_cache(maxsize=256)
def _names_store(path, mtime) -> bool:
    """Whether the grid file at ``path`` interpolates ``results_dir`` (``mtime``: cache
    key only)."""
    try:
        return "results_dir" in Path(path).read_text()
    except OSError:
        return True


@functools.lru_cache(maxsize=256)
def _grid(key):
    from psbench.harness.grid import load

    try:
        return load(key[0], results_dir=None if key[1] == "None" else key[1])
    except Exception:  # noqa: BLE001 - a page is still written without its grid
        return {}


def grid(name: str, results=None) -> dict:
    """The experiment's grid mapping, interpolations resolved with ``results_dir =
    results`` ({} when it has no readable grid). Cached per grid file and environment."""
    return copy.deepcopy(_grid(_cache_key(name, results)))


def grid_text(name: str) -> str | None:
    """The text of the experiment's grid YAML (None without one)."""
    from psbench import registry
    from psbench._shared.checks import PsbenchError

    try:
        path = registry.get("experiments", name).grid
    except PsbenchError:
        return None
    return path.read_text() if path is not None and path.is_file() else None


def scale_size(name: str, scale: str, results=None):
    """Image size of ``scale`` for experiment ``name`` (None when it has none)."""
    sc = (grid(name, results).get("scales") or {}).get(scale) or {}
    size = sc.get("size")
    if isinstance(size, list):
        size = size[0] if size else None
    return size


def load_store(results) -> tuple[pd.DataFrame, list[str]]:
    """Read the results store; returns (rows, warning messages) and never raises on bad files."""
    from psbench.harness.store import read_store

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        df = read_store(results)
    msgs = [str(w.message) for w in caught]
    return df, msgs


def expected_run_ids(experiment: str, scale: str, results=None) -> frozenset | None:
    """run_ids of the current definition of ``experiment`` at ``scale`` (None if the grid
    cannot be expanded here). Cached like :func:`grid`."""
    return _run_ids(_cache_key(experiment, results), scale)


def completeness(experiment: str, scale: str, rows: pd.DataFrame, results=None):
    """``(present, expected)``: ok runs of ``rows`` in the current grid at ``scale`` and
    the grid's size; None when it cannot be told (the grid cannot be expanded here, or no
    row matches its run ids, e.g. paths expanded from another folder)."""
    ids = expected_run_ids(experiment, scale, results)
    if not ids or rows is None or rows.empty or "run_id" not in rows:
        return None
    ok = rows[rows["status"] == "ok"] if "status" in rows else rows
    present = int(ok.loc[ok["run_id"].isin(ids), "run_id"].nunique())
    return (present, len(ids)) if present else None


@functools.lru_cache(maxsize=256)
def _run_ids(key, scale):
    try:
        from psbench.harness.grid import expand
        from psbench.harness.run import run_id

        spec = copy.deepcopy(_grid(key))
        if not spec:
            return None
        root = "results" if key[1] == "None" else key[1]     # as the harness hashes
        return frozenset(run_id(p, root=root) for p in expand(spec, scale))
    except Exception:  # noqa: BLE001
        return None


def select(df: pd.DataFrame, experiment: str, scale: str | None = None,
           status: str | None = "ok", current: bool = True, results=None) -> pd.DataFrame:
    """Rows of one experiment (``experiment`` column, else ``sweep``) at one scale.

    With ``current`` (default), rows whose run_id belongs to the experiment's current grid
    at ``scale`` are kept (stale rows of an older grid definition are ignored); when none
    match (e.g. relative data paths expanded from another folder), the scale is recognized
    by the image size of ``scales.<scale>.size`` instead; experiments without a size
    (cond, real data) then keep all rows. ``results`` is the store's folder, for grids
    whose paths refer to it (``${results_dir}``).
    """
    if df is None or df.empty:
        return df.iloc[0:0] if isinstance(df, pd.DataFrame) else pd.DataFrame()
    exp = df["experiment"] if "experiment" in df else pd.Series(index=df.index, dtype=object)
    key = exp.where(exp.notna(), df.get("sweep"))
    out = df[key == experiment]
    if status is not None and "status" in out:
        out = out[out["status"] == status]
    if scale is not None:
        ids = expected_run_ids(experiment, scale, results) if current else None
        if ids and out["run_id"].isin(ids).any():
            out = out[out["run_id"].isin(ids)]
        elif "size" in out:
            size = scale_size(experiment, scale, results)
            if size is not None:
                out = out[out["size"] == size]
    return out.reset_index(drop=True)


def aggregate(experiment: str, rows: pd.DataFrame) -> pd.DataFrame:
    """Long-format aggregate of one experiment's ok rows (the module's ``aggregate``)."""
    fn = getattr(experiment_module(experiment), "aggregate", None)
    if fn is None or rows is None or rows.empty:
        return long_frame([], experiment)
    out = fn(rows)
    if not isinstance(out, pd.DataFrame):
        out = long_frame(out, experiment)
    out = out.assign(experiment=experiment)
    return out[LONG_COLUMNS].reset_index(drop=True)


def thesis_frame(experiment: str) -> pd.DataFrame:
    """The thesis's values of an experiment (its module's ``THESIS``, nested
    ``{part: {row: {column: value}}}``) as a long frame ``part, row, column, value``."""
    values = getattr(experiment_module(experiment), "THESIS", None) or {}
    recs = [(p, r, c, v) for p, rows in values.items() for r, cols in rows.items()
            for c, v in cols.items()]
    return pd.DataFrame.from_records(recs, columns=["part", "row", "column", "value"])


def compare(experiment: str, agg: pd.DataFrame) -> pd.DataFrame:
    """Join an aggregate with the thesis's values: columns part, row, column, psbench,
    thesis, diff (psbench - thesis), n. Cells present on either side are kept."""
    th = thesis_frame(experiment).rename(columns={"value": "thesis"})
    ps = agg.drop(columns="experiment").rename(columns={"value": "psbench"}) if not agg.empty \
        else pd.DataFrame(columns=["part", "row", "column", "psbench", "n"])
    for f in (th, ps):
        for c in ("part", "row", "column"):
            f[c] = f[c].astype(str)
    out = pd.merge(ps, th, on=["part", "row", "column"], how="outer", sort=False)
    # thesis order first (parts, rows, columns as printed), then psbench's extra cells
    order = {}
    for f in (th, ps):
        for c in ("part", "row", "column"):
            for v in f[c]:
                order.setdefault((c, v), len(order))
    out = out.assign(_p=out["part"].map(lambda v: order[("part", v)]),
                     _r=out["row"].map(lambda v: order[("row", v)]),
                     _c=out["column"].map(lambda v: order[("column", v)]))
    out = out.sort_values(["_p", "_r", "_c"], kind="stable").drop(columns=["_p", "_r", "_c"])
    out["psbench"] = pd.to_numeric(out["psbench"], errors="coerce")
    out["thesis"] = pd.to_numeric(out["thesis"], errors="coerce")
    out["diff"] = out["psbench"] - out["thesis"]
    return out[["part", "row", "column", "psbench", "thesis", "diff", "n"]]
