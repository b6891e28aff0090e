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
changing the code that renders, reconstructs or compares.
"""
from __future__ import annotations

import hashlib
import io
import json
from pathlib import Path

import numpy as np

from .._shared.files import atomic_write

__all__ = ["StudyCache", "digest"]


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
    """The cache folder ``root`` (None: nothing is cached, every piece is computed)."""

    def __init__(self, root=None):
        self.root = Path(root).expanduser().resolve() if root else None

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
        if self.root is None:
            return compute(list(targets))
        path = self.root / "pairs" / digest(options) / f"{ref}.json"
        have = json.loads(path.read_text()) if path.is_file() else {}
        missing = [t for t in targets if t not in have]
        if missing:
            have.update(zip(missing, compute(missing)))
            atomic_write(path, json.dumps(have), fsync=False)
        return [have[t] for t in targets]
