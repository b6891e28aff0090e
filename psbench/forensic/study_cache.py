"""On-disk cache of the breech-face study, so that a study of hours resumes where it stopped.

A full-scale :mod:`~psbench.forensic.breechface_runs` run reconstructs 95 scans and
compares 4,465 pairs per map, at about 0.4 s a pair: hours per run. With a cache folder
(``study.cache``) every finished piece is kept, and a run that is stopped (or lost, or
re-run with more methods) redoes only what is missing:

``maps/<key>.npz``
    One scan rendered and reconstructed by one method label and integrated by one
    integrator: the band-passed map (float32, µm) and its per-scan rows. ``key`` is a
    digest of the scan's heights and valid mask (as the study loaded them) and of every
    parameter the map depends on (finish, metering, seed, label, pixel size, band-pass),
    then the integrator.
``pairs/<options>/<map>.json``
    The CMC rows of one reference map against each target map, keyed by the digest of
    the target map; ``<options>`` is a digest of the CMC options, ``<map>`` the
    reference map's digest. Written after each reference, so at most one reference's
    comparisons are redone after an interruption.

Keys are digests of the data themselves, so two studies (or a study and
``benchmarks/breechface_study.py``) that produce the same maps share their comparisons.
Files are written atomically. The cache does not know psbench's version: delete it after
changing the code that renders, reconstructs or compares (the comparison's options
include the CMC search's revision, :data:`~._cmc_search.SEARCH_REVISION`).

The pairs ``table`` (a Parquet file) carries comparisons from one checkout to another:
every comparison (``options, ref, target`` digests and the CMC row) that
:meth:`StudyCache.pairs` reads before comparing, and that :meth:`StudyCache.export`
brings up to date with the folder. The full-scale study's pairs table is committed
(``reports/data/breechface_pairs.parquet``): a fresh checkout re-renders and
re-reconstructs every map (minutes per run) and compares only the pairs whose maps
differ from the ones the table was made from (other code, or a machine whose arithmetic
differs), instead of comparing all of them again (hours per run). Being keyed by the
maps' own bytes, it cannot hand a changed map an old score.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
from pathlib import Path

import numpy as np

from .._shared.files import atomic_write

__all__ = ["StudyCache", "digest", "TABLE_COLUMNS"]

#: columns of a pairs table: the digests, then the CMC row of :func:`~.breechface.score_pairs`
TABLE_COLUMNS = ("options", "ref", "target", "count", "cells", "ccf", "dx", "dy", "theta",
                "seconds")


def digest(*parts) -> str:
    """A 20-hex-digit digest of arrays (shape, dtype and bytes) and json-able values."""
    h = hashlib.sha1()
    for p in parts:
        if isinstance(p, np.ndarray):
            a = np.ascontiguousarray(p)
            h.update(f"{a.shape}{a.dtype.str}".encode())
            h.update(a.tobytes())
        else:
            h.update(json.dumps(p, sort_keys=True, default=str).encode())
        h.update(b"|")
    return h.hexdigest()[:20]


class StudyCache:
    """The cache folder ``root`` (None: nothing is cached, every piece is computed) and
    the optional pairs ``table`` of earlier comparisons (read-only until :meth:`export`)."""

    def __init__(self, root=None, table=None):
        self.root = Path(root).expanduser().resolve() if root else None
        self.table = Path(table).expanduser().resolve() if table else None
        self._known = None

    def __getstate__(self):             # worker processes load the table themselves
        return {**self.__dict__, "_known": None}

    def _from_table(self, options, ref):
        """{target digest: row} of the table for this options digest and reference."""
        if self.table is None:
            return {}
        if self._known is None:
            self._known = {}
            t = _read_table(self.table)
            fields = list(TABLE_COLUMNS[3:])
            for (o, r), g in t.groupby(["options", "ref"], sort=False):
                rows = g[fields].to_dict("records")
                self._known[(o, r)] = dict(zip(g["target"], rows))
        return self._known.get((options, ref), {})

    def maps(self, keys, compute):
        """Maps stored under ``keys``, or ``compute()``'s (then stored under them).

        ``compute()`` returns ``(maps, rows)``: one 2-D array and one list of json-able
        dicts per key (one solve gives the maps of several integrators: all are computed
        when any is missing). Returns the same, loaded or computed.
        """
        keys = list(keys)
        paths = [self.root / "maps" / f"{k}.npz" for k in keys] if self.root else []
        if paths and all(p.is_file() for p in paths):
            maps, rows = [], []
            for p in paths:
                with np.load(p) as f:
                    maps.append(f["map"])
                    rows.append(json.loads(str(f["rows"])))
            return maps, rows
        maps, rows = compute()
        for p, m, r in zip(paths, maps, rows):
            buf = io.BytesIO()
            np.savez(buf, map=np.asarray(m, np.float32), rows=json.dumps(r))
            atomic_write(p, buf.getvalue(), fsync=False)
        return maps, rows

    def pairs(self, options, ref, targets, compute):
        """Rows of reference map digest ``ref`` against each of ``targets`` (digests).

        ``compute(missing)`` returns the rows (dicts) of the targets not yet stored, in
        order; they are stored with the others. Returns the rows of ``targets`` in order.
        """
        if self.root is None and self.table is None:
            return compute(list(targets))
        opt = digest(options)
        path = self.root / "pairs" / opt / f"{ref}.json" if self.root else None
        have = json.loads(path.read_text()) if path and path.is_file() else {}
        known = self._from_table(opt, ref)
        have.update({t: known[t] for t in targets if t not in have and t in known})
        missing = [t for t in targets if t not in have]
        if missing:
            have.update(zip(missing, compute(missing)))
        if path and (missing or not path.is_file()):
            atomic_write(path, json.dumps(have), fsync=False)
        return [have[t] for t in targets]

    def export(self):
        """Merge every comparison of the folder into the pairs table (atomically, under a
        lock: concurrent runs may export at once). Returns the table's row count."""
        import pandas as pd

        if self.table is None or self.root is None:
            return 0
        rows = []
        for f in sorted((self.root / "pairs").glob("*/*.json")):
            for target, r in json.loads(f.read_text()).items():
                rows.append({"options": f.parent.name, "ref": f.stem, "target": target,
                             **{k: r.get(k) for k in TABLE_COLUMNS[3:]}})
        with _locked(self.table):
            old = _read_table(self.table)
            new = pd.DataFrame(rows, columns=list(TABLE_COLUMNS))
            t = pd.concat([old, new], ignore_index=True) if len(old) else new
            t = (t.drop_duplicates(["options", "ref", "target"], keep="last")
                  .sort_values(["options", "ref", "target"], kind="stable")
                  .reset_index(drop=True))
            t = t.astype({"count": "int32", "cells": "int32"})
            buf = io.BytesIO()
            t.to_parquet(buf, index=False, compression="zstd")
            atomic_write(self.table, buf.getvalue())
        self._known = None
        return len(t)


def _read_table(path):
    import pandas as pd

    from .._shared.checks import PsbenchError

    if not Path(path).is_file():
        return pd.DataFrame(columns=list(TABLE_COLUMNS))
    try:
        t = pd.read_parquet(path)
    except Exception as e:                      # not Parquet, truncated, ...
        raise PsbenchError(f"study pairs_table {path}: not a readable Parquet table "
                           f"({e})") from None
    missing = [c for c in TABLE_COLUMNS if c not in t.columns]
    if missing:
        raise PsbenchError(f"study pairs_table {path}: missing columns {missing}; expected "
                           f"{', '.join(TABLE_COLUMNS)}")
    return t[list(TABLE_COLUMNS)]


@contextlib.contextmanager
def _locked(path):
    """An exclusive lock on ``.<name>.lock`` beside ``path`` (where fcntl exists)."""
    lock = path.with_name(f".{path.name}.lock")
    lock.parent.mkdir(parents=True, exist_ok=True)
    with open(lock, "a") as fh:
        try:
            import fcntl
        except ImportError:             # not POSIX: no other writer is expected
            yield
            return
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)
