"""The Parquet results store.

Layout under a root folder (default ``results/`` in the current directory, or the
``PSBENCH_RESULTS`` environment variable)::

    <root>/runs/<sweep>/<run_id>.parquet     one file per run, written atomically
    <root>/runs/<sweep>/compact.parquet      the sweep's runs merged by :func:`compact`

Every row of the store is under ``<root>/runs``, so Parquet readers read the whole
store, compacted or not, in one line (``pd.read_parquet("results/runs")``; hidden files
are temporary files and locks, which those readers skip). ``<sweep>`` is the experiment
name (``+experiment=table5_3``) or the ``sweep=`` name of command-line runs (default
``adhoc``). Each file is first written to a hidden temporary name in the same folder
(``.<name>.tmp.<pid>.<hex>.<host>``) and then renamed with :func:`os.replace`, so a
reader sees either the whole file or nothing. A run is identified by ``(sweep,
run_id)``; re-running it replaces its file, and readers keep the latest row (largest
``utc``): until the next compaction a re-run compacted run is in two files.

Integrity: files are written with Parquet page checksums and a digest of their values
in the footer, and every read verifies both; a file whose schema version is the current
one must hold exactly the current columns and types. A file failing a check is named in
a :class:`StoreWarning` and skipped (``psbench-results verify`` lists them); the skip
check of the runners (:func:`stored_status`) and compaction move it aside to
``<root>/corrupt/<sweep>/<name>.<utc>`` (kept, never deleted), so its runs are computed
again. Compactions of one sweep are serialized by a
lock file (``runs/<sweep>/.compact.lock``) and a per-run file is removed only after its
row was read back from the new compact file. Stores of the previous layout
(``<root>/compact/<sweep>.parquet``) are read, and moved by the next compaction.
"""
from __future__ import annotations

import contextlib
import os
import time
import warnings
from pathlib import Path

import pyarrow as pa
import pyarrow.compute  # noqa: F401 - pa.compute
import pyarrow.parquet as pq

from .._shared.checks import PsbenchError
from .._shared.files import HOST, atomic_write
from .schema import COLUMNS, META_KEY, REQUIRED, SCHEMA, SCHEMA_VERSION, conform, row_table

__all__ = ["default_root", "run_path", "compact_path", "write_row", "write_rows",
           "stored_status", "read_run", "read_store", "compact", "temp_files", "dead_temp",
           "check_writable", "StoreWarning", "COMPACT_NAME"]

#: name of a sweep's compacted file, beside its per-run files
COMPACT_NAME = "compact.parquet"
_LOCK_NAME = ".compact.lock"


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


def compact_path(root, sweep) -> Path:
    """Path of the compacted file of ``sweep``."""
    return default_root(root) / "runs" / _check_name(sweep) / COMPACT_NAME


def _legacy_compact(root, sweep) -> Path:
    return default_root(root) / "compact" / f"{_check_name(sweep)}.parquet"


#: footer key holding the digest of the file's values (:func:`_digest`)
DIGEST_KEY = b"psbench.values_sha256"


def _digest(table: pa.Table) -> bytes:
    """sha256 of every value of ``table``, column by column: a changed value that the
    page checksums miss (a flip in a page header or the footer) still fails the read."""
    import hashlib

    h = hashlib.sha256()
    for name in table.column_names:
        h.update(name.encode() + b"\0" + repr(table.column(name).to_pylist()).encode() + b"\0")
    return h.hexdigest().encode()


def _write_parquet(table: pa.Table, fh) -> None:
    meta = dict(table.schema.metadata or {})
    meta[DIGEST_KEY] = _digest(table)
    pq.write_table(table.replace_schema_metadata(meta), fh, compression="zstd",
                   write_page_checksum=True)


def _atomic_write(table: pa.Table, path: Path) -> Path:
    return atomic_write(path, lambda fh: _write_parquet(table, fh))


def check_writable(root, sweep=None) -> Path:
    """Refuse (one line) a store where rows cannot be written, before any work.

    Writes and removes a temporary file in ``<root>/runs[/<sweep>]`` or, when that
    does not exist yet, in its nearest existing parent (permission bits alone do not
    tell: root ignores them, read-only mounts do not show in them).
    """
    root = default_root(root)
    d = root / "runs" / _check_name(sweep) if sweep is not None else root / "runs"
    base = d.absolute()
    while not base.exists() and base.parent != base:    # nothing is created here
        base = base.parent
    try:
        if not base.is_dir():
            raise NotADirectoryError(20, "Not a directory", str(base))
        probe = base / f".write-test.tmp.{os.getpid()}.0.{HOST}"
        with open(probe, "wb") as fh:
            fh.write(b"psbench")
        probe.unlink()
    except OSError as exc:
        raise PsbenchError(f"results_dir={str(root)!r} is not writable ({exc.strerror or exc}: "
                           f"{exc.filename or d}); choose another with results_dir=DIR or "
                           "$PSBENCH_RESULTS") from None
    return root


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


class _Vanished(Exception):
    """A listed file was removed (by a compaction) before it was read."""


def _check_schema(path, schema):
    """Current-version files hold exactly the current columns and types: a difference
    is corruption (e.g. a flipped bit in the footer), not an older layout."""
    meta = schema.metadata or {}
    if meta.get(META_KEY) != str(SCHEMA_VERSION).encode():
        return None
    for f in schema:
        want = SCHEMA.field(f.name).type if f.name in COLUMNS else None
        if want is None or f.type != want:
            return (f"column {f.name!r} ({f.type}) is not in schema version {SCHEMA_VERSION}"
                    if want is None else f"column {f.name!r} is {f.type}, expected {want}")
    return None


def _read_file(path: Path, columns=None, *, missing_ok=False, set_aside=False):
    """Read a store file conformed to SCHEMA, verifying its page checksums and its
    values' digest; None (with a warning) if corrupt/foreign. A file that vanished
    raises :class:`_Vanished` when ``missing_ok`` (the caller re-lists), else it is
    skipped silently. ``columns`` selects columns after the whole file was read and
    verified (a run is "stored" only when its whole row reads back). With
    ``set_aside``, a corrupt file is moved to ``<root>/corrupt/`` (:func:`_set_aside`)
    so that its runs are computed again."""
    try:
        with open(path, "rb") as fh:
            ident = os.fstat(fh.fileno()).st_ino
            why = _check_file(path, fh)
            if isinstance(why, pa.Table):
                table = why
                if columns is not None:
                    return table.select([c for c in columns if c in table.column_names])
                return conform(table)
    except FileNotFoundError:
        if missing_ok:
            raise _Vanished(path) from None
        return None
    if why.startswith("not a psbench"):
        warnings.warn(f"psbench results store: skipping {path}: {why}", StoreWarning,
                      stacklevel=3)
        return None
    moved = _set_aside(path, ident) if set_aside else None
    tail = (f"; moved aside to {moved}, its runs will be computed again" if moved else
            "; could not be moved aside (read-only store?)" if set_aside else "")
    warnings.warn(f"psbench results store: skipping {path}: {why}{tail}", StoreWarning,
                  stacklevel=3)
    return None


def _check_file(path, fh):
    """The file's whole table when it reads back intact, else why not (text)."""
    try:
        pf = pq.ParquetFile(fh, page_checksum_verification=True)
        schema = pf.schema_arrow
        meta = schema.metadata or {}
        names = set(schema.names)
        if META_KEY not in meta or not set(REQUIRED) <= names:
            return (f"not a psbench results file (missing schema metadata or columns "
                    f"{list(REQUIRED)})")
        bad = _check_schema(path, schema)
        if bad is not None:
            return f"corrupt ({bad})"
        table = pf.read()
        want = meta.get(DIGEST_KEY)
        if want is not None and _digest(table) != want:
            return "corrupt (its values do not match the digest written with them)"
        return table
    except Exception as exc:  # noqa: BLE001 - any unreadable file is skipped, never fatal
        return f"unreadable ({type(exc).__name__}: {exc})"


def _set_aside(path: Path, ident):
    """Move the corrupt file ``path`` (inode ``ident``, as read) to
    ``<root>/corrupt/<sweep>/<name>.<utc>`` (kept for inspection, out of the readers'
    way); a newer file written at ``path`` meanwhile is put back. Returns the new path,
    or None when it could not be moved (read-only store, already moved)."""
    path = Path(path)
    root = path.parent.parent.parent if path.parent.parent.name == "runs" else path.parent.parent
    stamp = _utcnow().strftime("%Y%m%dT%H%M%S%f")
    dest = root / "corrupt" / path.parent.name / f"{path.name}.{stamp}"
    try:
        dest.parent.mkdir(parents=True, exist_ok=True)
        os.rename(path, dest)
    except OSError:
        return None
    with contextlib.suppress(OSError):
        if dest.stat().st_ino != ident:          # not the file that failed: put it back
            with contextlib.suppress(FileExistsError):
                os.link(dest, path)
            dest.unlink()
            return None
    return dest


def _files(root: Path, sweep=None, per_run=True):
    """(compact files, per-run files) currently visible in the store."""
    runs_dir = root / "runs"
    if sweep is None:
        dirs = sorted(p for p in runs_dir.iterdir() if p.is_dir() and not p.name.startswith(".")) \
            if runs_dir.is_dir() else []
        legacy = root / "compact"
        comp = sorted(p for p in legacy.glob("*.parquet") if _visible(p)) if legacy.is_dir() else []
    else:
        sweep = _check_name(sweep)
        dirs = [runs_dir / sweep] if (runs_dir / sweep).is_dir() else []
        old = _legacy_compact(root, sweep)
        comp = [old] if old.is_file() else []
    runs = []
    for d in dirs:
        for p in sorted(d.glob("*.parquet")):
            if not _visible(p):
                continue
            if p.name == COMPACT_NAME:
                comp.append(p)
            elif per_run:
                runs.append(p)
    return comp, runs


def _read_all(list_files, reader, attempts=5):
    """Read the listed files; when a compaction removed one between listing and
    reading, list and read again (its rows are then in the new compact file)."""
    for i in range(attempts):
        files = list_files()
        try:
            return [(p, reader(p)) for p in files]
        except _Vanished:
            if i == attempts - 1:
                raise PsbenchError("the results store keeps changing under the reader (a "
                                   "compaction is running); try again") from None
            time.sleep(0.05 * (i + 1))
    return []


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
    name = sweep if sweep is not None else experiment

    def listing():
        comp, runs = _files(root, name)
        return comp + runs

    read = _read_all(listing, lambda p: _read_file(p, missing_ok=True))
    tables = [t for _, t in read if t is not None]
    table = pa.concat_tables(tables) if tables else SCHEMA.empty_table()
    df = table.to_pandas()
    df = _dedup(df)
    if experiment is not None:
        df = df[df["experiment"] == experiment].reset_index(drop=True)
    if status is not None:
        df = df[df["status"] == status].reset_index(drop=True)
    return df[list(COLUMNS)]


def stored_status(root, sweep, run_ids=None, *, set_aside=True) -> dict:
    """``{run_id: status}`` of the runs stored for ``sweep`` (the skip check).

    A run counts as stored only when its whole row reads back: every file is read and
    verified as :func:`read_store` reads it, and a corrupt one is moved aside to
    ``<root>/corrupt/`` (named in a :class:`StoreWarning`) so its runs are redone.
    With ``run_ids``, only those runs' per-run files (and the compact file) are read.
    """
    root = default_root(root)

    def listing():
        comp, runs = _files(root, sweep, per_run=run_ids is None)
        if run_ids is not None:
            runs = [p for p in (run_path(root, sweep, r) for r in run_ids) if p.is_file()]
        return comp + runs

    read = _read_all(listing, lambda p: _read_file(p, columns=["run_id", "status", "utc"],
                                                    missing_ok=True, set_aside=set_aside))
    latest = {}
    for _, t in read:
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

    def listing():
        return [f for f in (run_path(root, sweep, run_id), compact_path(root, sweep),
                            _legacy_compact(root, sweep)) if f.is_file()]

    best = None
    for _, t in _read_all(listing, lambda p: _read_file(p, missing_ok=True)):
        if t is None:
            continue
        for r in t.filter(pa.compute.equal(t.column("run_id"), run_id)).to_pylist():
            if best is None or (r["utc"] is not None and best["utc"] is not None
                                and r["utc"] > best["utc"]):
                best = r
    return best


# ---------------------------------------------------------------------------- temporaries
def temp_files(root=None) -> list[Path]:
    """Hidden temporary files (``.*.tmp.*``) left in the store by writers."""
    root = default_root(root)
    out = []
    for d in (root / "runs", root / "compact"):
        if d.is_dir():
            out += list(d.glob(".*.tmp.*")) + list(d.glob("*/.*.tmp.*"))
    return sorted(set(out))


def _pid_alive(pid) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:          # EPERM: it exists (another user's)
        return True
    return True


def dead_temp(path, *, now=None, min_age=3600.0, grace=2.0) -> bool:
    """True when the temporary file's writer is provably gone: written on this host by
    a process that no longer exists (and older than ``grace`` seconds), or untouched
    for ``min_age`` seconds (a writer on another host)."""
    path = Path(path)
    try:
        age = (time.time() if now is None else now) - path.stat().st_mtime
    except OSError:
        return False
    if age > min_age:
        return True
    parts = path.name.split(".tmp.", 1)[-1].split(".", 2)     # pid, hex, host
    if len(parts) == 3 and parts[0].isdigit() and parts[2] == HOST and age > grace:
        return not _pid_alive(int(parts[0]))
    return False


def clean_temps(root=None, *, min_age=3600.0, grace=2.0) -> list[Path]:
    """Remove the store's temporary files whose writers are provably dead
    (:func:`dead_temp`)."""
    removed = []
    now = time.time()
    for p in temp_files(root):
        if dead_temp(p, now=now, min_age=min_age, grace=grace):
            with contextlib.suppress(OSError):
                p.unlink()
                removed.append(p)
    return removed


# ---------------------------------------------------------------------------- compaction
@contextlib.contextmanager
def _locked(folder: Path):
    """Exclusive lock of one sweep's compaction (blocks until the holder is done)."""
    folder.mkdir(parents=True, exist_ok=True)
    fh = open(folder / _LOCK_NAME, "a+b")
    try:
        try:
            import fcntl
        except ImportError:  # pragma: no cover - not POSIX: no lock
            fcntl = None
        if fcntl is not None:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
        yield
    finally:
        fh.close()          # releases the lock


def _sig(st):
    return (st.st_mtime_ns, st.st_size, st.st_ino)


def _remove_merged(p: Path, sig) -> bool:
    """Remove per-run file ``p`` if it is still the file that was merged (``sig``).

    The file is first renamed aside (atomic), so a writer replacing ``p`` meanwhile is
    never lost: if what was moved aside is not the merged file, it is put back unless
    an even newer ``p`` exists by then."""
    aside = p.with_name(f".{p.name}.tmp.{os.getpid()}.merged.{HOST}")
    try:
        os.rename(p, aside)
    except OSError:
        return False
    try:
        moved = _sig(aside.stat())
        if moved != sig:
            with contextlib.suppress(FileExistsError):
                os.link(aside, p)          # create-if-absent: never over a newer file
            return False
        return True
    finally:
        with contextlib.suppress(OSError):
            aside.unlink()


def compact(root=None, *, sweep=None, min_tmp_age=3600.0, verbose=False) -> dict:
    """Merge each sweep's per-run files into ``<root>/runs/<sweep>/compact.parquet``.

    Under the sweep's lock, the merged rows (previous compact file + per-run files) are
    de-duplicated by ``run_id`` (latest ``utc`` wins) and written atomically; the new
    file is read back, and only the per-run files whose row is in it (and that did not
    change since they were read) are removed. Corrupt files are moved aside
    (:func:`_set_aside`), foreign ones left in place (with a warning). Temporary files
    whose writers are provably dead (:func:`dead_temp`) are removed.

    Returns
    -------
    dict
        ``{sweep: number of rows in its compact file}``.
    """
    root = default_root(root)
    runs_dir = root / "runs"
    names = [sweep] if sweep is not None else sorted(
        {p.name for p in runs_dir.iterdir() if p.is_dir() and not p.name.startswith(".")}
        if runs_dir.is_dir() else set())
    if sweep is None and (root / "compact").is_dir():
        names = sorted(set(names) | {p.stem for p in (root / "compact").glob("*.parquet")
                                     if _visible(p)})
    out = {}
    for name in names:
        d = runs_dir / _check_name(name)
        with _locked(d):
            n = _compact_one(root, name, d, verbose)
        if n is not None:
            out[name] = n
    clean_temps(root, min_age=min_tmp_age)
    return out


def _compact_one(root, name, d, verbose):
    comp, runs = _files(root, name)
    legacy = [p for p in comp if p.parent != d]
    if not runs and not legacy:
        return None
    tables, merged = [], []
    for p in comp + runs:
        try:
            st = p.stat()
        except OSError:
            continue
        t = _read_file(p, set_aside=True)     # a corrupt compact file is kept, not overwritten
        if t is None:
            continue
        tables.append(t)
        if p not in comp:
            rid = t.column("run_id")[0].as_py() if t.num_rows == 1 else None
            merged.append((p, _sig(st), rid, t.column("utc")[0].value if t.num_rows == 1
                           else None))
    if not tables:
        return None
    df = _dedup(pa.concat_tables(tables).to_pandas())
    table = pa.Table.from_pandas(df[list(COLUMNS)], schema=SCHEMA, preserve_index=False)
    target = d / COMPACT_NAME
    _atomic_write(table, target)
    # read the new file back: a per-run file goes only if its row is in it
    back = _read_file(target, columns=["run_id", "utc"])
    have = {}
    if back is not None:
        for rid, u in zip(back.column("run_id").to_pylist(), back.column("utc")):
            have[rid] = max(have.get(rid, -1), -1 if u.value is None else u.value)
    removed = 0
    for p, sig, rid, utc in merged:    # its row, or a newer one of the run, is in the file
        kept = rid in have and (utc is None or have[rid] >= utc)
        if kept and _remove_merged(p, sig):
            removed += 1
    if back is not None:
        for p in legacy:
            with contextlib.suppress(OSError):
                p.unlink()
    if verbose:
        print(f"compacted {removed} run files into {target} ({table.num_rows} rows)")
    return table.num_rows
