"""The Parquet results store.

Layout under a root folder (default ``results/`` in the current directory, or the
``PSBENCH_RESULTS`` environment variable)::

    <root>/runs/<sweep>/<run_id>.parquet     one file per run, written atomically
    <root>/compact/<sweep>.parquet           per-sweep files made by :func:`compact`

``<sweep>`` is the experiment name (``+experiment=table5_3``) or the ``sweep=`` name of
command-line runs (default ``adhoc``). Each per-run file is first written to a hidden
temporary name in the same folder (``.<run_id>.parquet.tmp.<pid>.<rand>``) and then
renamed with :func:`os.replace`, so a reader sees either the whole file or nothing;
readers ignore hidden and temporary files. A run is identified by ``(sweep, run_id)``;
re-running it replaces its file, and readers keep the latest row (largest ``utc``).
"""
from __future__ import annotations

import os
import time
import warnings
from pathlib import Path

import pyarrow as pa
import pyarrow.compute  # noqa: F401 - pa.compute
import pyarrow.parquet as pq

from .._checks import PsbenchError
from .._fs import atomic_write
from .schema import COLUMNS, META_KEY, REQUIRED, SCHEMA, SCHEMA_VERSION, conform, row_table

__all__ = ["default_root", "run_path", "write_row", "write_rows", "stored_status", "read_run",
           "read_store", "compact", "StoreWarning"]


class StoreWarning(UserWarning):
    """A file in the results store was skipped (corrupt or not a psbench file)."""


def default_root(root=None) -> Path:
    """``root`` if given, else ``$PSBENCH_RESULTS``, else ``results`` (relative to CWD)."""
    if root is None:
        root = os.environ.get("PSBENCH_RESULTS") or "results"
    return Path(root).expanduser()


def _check_name(name, what="sweep"):
    name = str(name)
    if not name or name.startswith(".") or "/" in name or "\\" in name or name in ("..",):
        raise PsbenchError(f"{what} name must be a plain folder name, got {name!r}")
    return name


def run_path(root, sweep, run_id) -> Path:
    """Path of the per-run file of ``run_id`` in ``sweep``."""
    return default_root(root) / "runs" / _check_name(sweep) / f"{_check_name(run_id, 'run_id')}.parquet"


def _atomic_write(table: pa.Table, path: Path) -> Path:
    return atomic_write(path, lambda fh: pq.write_table(table, fh, compression="zstd"))


def write_row(root, row: dict) -> Path:
    """Write one run's row to ``<root>/runs/<sweep>/<run_id>.parquet`` atomically.

    ``row`` must hold ``run_id`` and ``sweep``; missing columns are null,
    ``schema_version`` and ``utc`` are filled in when absent.
    """
    return write_rows(root, [row])[0]


def write_rows(root, rows) -> list[Path]:
    """Write several rows, one atomic per-run file each."""
    out = []
    for row in rows:
        row = dict(row)
        for key in ("run_id", "sweep"):
            if not row.get(key):
                raise PsbenchError(f"row needs a non-empty {key!r}, got {row.get(key)!r}")
        row.setdefault("schema_version", SCHEMA_VERSION)
        if row.get("utc") is None:
            row["utc"] = _utcnow()
        out.append(_atomic_write(row_table([row]), run_path(root, row["sweep"], row["run_id"])))
    return out


def _utcnow():
    import datetime as _dt

    return _dt.datetime.now(_dt.timezone.utc)


def _visible(path: Path) -> bool:
    return path.suffix == ".parquet" and not path.name.startswith(".")


def _read_file(path: Path, columns=None):
    """Read a store file conformed to SCHEMA; None (with a warning) if corrupt/foreign."""
    try:
        pf = pq.ParquetFile(path)
        meta = pf.schema_arrow.metadata or {}
        names = set(pf.schema_arrow.names)
        if META_KEY not in meta or not set(REQUIRED) <= names:
            warnings.warn(f"psbench results store: skipping {path}: not a psbench results "
                          f"file (missing schema metadata or columns {list(REQUIRED)})",
                          StoreWarning, stacklevel=3)
            return None
        cols = None if columns is None else [c for c in columns if c in names]
        table = pf.read(columns=cols)
        if columns is not None:
            return table
        return conform(table)
    except Exception as exc:  # noqa: BLE001 - any unreadable file is skipped, never fatal
        warnings.warn(f"psbench results store: skipping {path}: unreadable ({type(exc).__name__}: "
                      f"{exc})", StoreWarning, stacklevel=3)
        return None


def _files(root: Path, sweep=None, per_run=True):
    """(compact files, per-run files) currently visible in the store."""
    compact_dir, runs_dir = root / "compact", root / "runs"
    if sweep is None:
        comp = sorted(p for p in compact_dir.glob("*.parquet") if _visible(p)) \
            if compact_dir.is_dir() else []
        runs = sorted(p for p in runs_dir.glob("*/*.parquet") if _visible(p)) \
            if runs_dir.is_dir() else []
    else:
        sweep = _check_name(sweep)
        c = compact_dir / f"{sweep}.parquet"
        comp = [c] if c.is_file() else []
        d = runs_dir / sweep
        runs = sorted(p for p in d.glob("*.parquet") if _visible(p)) \
            if d.is_dir() and per_run else []
    return comp, runs


def _dedup(df):
    if df.empty:
        return df
    df = df.sort_values("utc", kind="stable", na_position="first")
    df = df.drop_duplicates(subset=["sweep", "run_id"], keep="last")
    return df.sort_values(["sweep", "utc"], kind="stable").reset_index(drop=True)


def read_store(root=None, experiment=None, *, sweep=None, status=None):
    """Read every run row of the store into a DataFrame.

    Parameters
    ----------
    root : str or Path, optional
        Store root; default ``$PSBENCH_RESULTS`` or ``results``.
    experiment : str, optional
        Keep only rows of this experiment.
    sweep : str, optional
        Read only this store folder (experiment or sweep name).
    status : str, optional
        Keep only rows with this status ("ok" or "failed").

    Returns
    -------
    pandas.DataFrame
        One row per ``(sweep, run_id)`` (latest ``utc`` wins), columns :data:`COLUMNS`.
        Corrupt or foreign Parquet files are named in a :class:`StoreWarning` and
        skipped; an empty or missing store gives an empty frame with all columns.
    """
    root = default_root(root)
    comp, runs = _files(root, sweep if sweep is not None else experiment)
    tables = [t for t in (_read_file(p) for p in comp + runs) if t is not None]
    table = pa.concat_tables(tables) if tables else SCHEMA.empty_table()
    df = table.to_pandas()
    df = _dedup(df)
    if experiment is not None:
        df = df[df["experiment"] == experiment].reset_index(drop=True)
    if status is not None:
        df = df[df["status"] == status].reset_index(drop=True)
    return df[list(COLUMNS)]


def stored_status(root, sweep, run_ids=None) -> dict:
    """``{run_id: status}`` of the runs stored for ``sweep`` (cheap: reads three columns).

    With ``run_ids``, only those runs' per-run files (and the compact file) are read.
    """
    root = default_root(root)
    comp, runs = _files(root, sweep, per_run=run_ids is None)
    if run_ids is not None:
        runs = [p for p in (run_path(root, sweep, r) for r in run_ids) if p.is_file()]
    latest = {}
    for p in comp + runs:
        t = _read_file(p, columns=["run_id", "status", "utc"])
        if t is None:
            continue
        for rid, st, utc in zip(*(t.column(c).to_pylist() for c in ("run_id", "status", "utc"))):
            old = latest.get(rid)
            if old is None or (utc is not None and (old[1] is None or utc >= old[1])):
                latest[rid] = (st, utc)
    return {k: v[0] for k, v in latest.items()}


def read_run(root, sweep, run_id):
    """The stored row (dict) of one run, or None."""
    root = default_root(root)
    p = run_path(root, sweep, run_id)
    files = [p] if p.is_file() else []
    c = root / "compact" / f"{_check_name(sweep)}.parquet"
    if c.is_file():
        files.append(c)
    best = None
    for f in files:
        t = _read_file(f)
        if t is None:
            continue
        for r in t.filter(pa.compute.equal(t.column("run_id"), run_id)).to_pylist():
            if best is None or (r["utc"] is not None and best["utc"] is not None
                                and r["utc"] > best["utc"]):
                best = r
    return best


def compact(root=None, *, sweep=None, min_tmp_age=3600.0, verbose=False) -> dict:
    """Merge per-run files into ``<root>/compact/<sweep>.parquet`` (one per sweep).

    The merged rows (previous compact file + per-run files) are de-duplicated by
    ``run_id`` (latest ``utc`` wins) and written atomically; only then are the merged
    per-run files removed (each only if it did not change since it was read).
    Corrupt/foreign files are left in place (with a warning). Hidden temporary files
    older than ``min_tmp_age`` seconds (left by killed writers) are removed.

    Returns
    -------
    dict
        ``{sweep: number of rows in its compact file}``.
    """
    root = default_root(root)
    runs_dir = root / "runs"
    names = [sweep] if sweep is not None else (
        sorted(p.name for p in runs_dir.iterdir() if p.is_dir() and not p.name.startswith("."))
        if runs_dir.is_dir() else [])
    out = {}
    now = time.time()
    for name in names:
        d = runs_dir / _check_name(name)
        if d.is_dir():
            for tmp in d.glob(".*.tmp.*"):
                try:
                    if now - tmp.stat().st_mtime > min_tmp_age:
                        tmp.unlink()
                except OSError:
                    pass
        comp, runs = _files(root, name)
        if not runs:
            continue
        tables, merged = [], []
        for p in comp + runs:
            try:
                st = p.stat()
            except OSError:
                continue
            t = _read_file(p)
            if t is None:
                continue
            tables.append(t)
            if p in runs:
                merged.append((p, (st.st_mtime_ns, st.st_size, st.st_ino)))
        if not merged:
            continue
        df = _dedup(pa.concat_tables(tables).to_pandas())
        table = pa.Table.from_pandas(df[list(COLUMNS)], schema=SCHEMA, preserve_index=False)
        target = root / "compact" / f"{name}.parquet"
        _atomic_write(table, target)
        for p, sig in merged:
            try:
                st = p.stat()
                if (st.st_mtime_ns, st.st_size, st.st_ino) == sig:
                    p.unlink()
            except OSError:
                pass
        out[name] = table.num_rows
        if verbose:
            print(f"compacted {len(merged)} run files into {target} ({table.num_rows} rows)")
    return out
