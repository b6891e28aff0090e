"""The ``-m`` sweep callback: done/total/ETA lines, a summary table and the comparison sheet.

Hydra calls :class:`SweepCallback` (registered in ``psbench/conf/config.yaml``) in the
launching process before and after a sweep, and in the process running each job after
that job (a joblib worker, or the same process with ``hydra/launcher=basic``). Jobs
report to each other through one small json-lines file: the launching process writes the
job count and start time, every finished job appends its run id, status and picture
folder and prints ``sweep NAME: done/total done | elapsed | ETA`` on stderr. At the end
the launching process prints the summary table (best first: lowest mean NE, else lowest
IE) and writes the comparison sheet (:func:`psbench.harness.sheet.build_sheet`), then
removes the file.
"""
from __future__ import annotations

import atexit
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

from ._rows import _num, rank, varying

try:  # Hydra is a dependency; the class stays importable without it for the helpers
    from hydra.experimental.callback import Callback
except ImportError:  # pragma: no cover
    Callback = object

__all__ = ["SweepCallback", "count_jobs", "summary_table", "rank", "varying", "cleanup"]


def count_jobs(config) -> int | None:
    """Number of jobs of the sweep given by ``config.hydra.overrides.task`` (None when
    it cannot be worked out)."""
    try:
        from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
        from hydra.core.override_parser.overrides_parser import OverridesParser

        over = list(config.hydra.overrides.task)
        parsed = OverridesParser.create().parse_overrides(over)
        return len(BasicSweeper.split_arguments(parsed, None)[0])
    except Exception:  # noqa: BLE001 - a display nicety: never stop a sweep for it
        return None


def _hms(s):
    from .progress import _hms as f

    return f(s)


def _read(path):
    """Header and records of the progress file."""
    try:
        lines = Path(path).read_text().splitlines()
    except OSError:
        return {}, []
    recs = []
    for ln in lines:
        try:
            recs.append(json.loads(ln))
        except ValueError:
            continue
    head = recs[0] if recs and recs[0].get("header") else {}
    return head, [r for r in recs if not r.get("header")]


def _cell(v):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, str) and v.startswith("/"):
        return Path(v).name
    return str(v)


def summary_table(rows, axes=None) -> str:
    """The summary table of a sweep as text, best first."""
    rows = rank(rows)
    axes = axes or varying(rows)
    head = ["#", *axes, "NE mean (deg)", "NE median (deg)", "IE (% of range)", "time (s)",
            "status"]
    def num(r, k):
        v = _num(r.get(k))
        return "-" if v is None else f"{v:.2f}"

    body = [[str(i), *(_cell(r.get(a)) for a in axes), *(num(r, k) for k in
             ("ne_mean", "ne_median", "ie_rel", "t_total")), str(r.get("status") or "-")]
            for i, r in enumerate(rows, 1)]
    width = [max(len(h), *(len(b[j]) for b in body)) if body else len(h)
             for j, h in enumerate(head)]
    left = set(range(len(axes) + 1)) | {len(head) - 1}      # text columns; numbers right

    def fmt(cells):
        return "  ".join(c.ljust(w) if j in left else c.rjust(w)
                         for j, (c, w) in enumerate(zip(cells, width))).rstrip()
    return "\n".join([fmt(head), fmt(["-" * w for w in width])] + [fmt(b) for b in body])


class SweepCallback(Callback):
    """Hydra callback of ``psbench -m``: progress, summary table, comparison sheet."""

    def __init__(self, **_):
        self.path = None

    # ------------------------------------------------------------------ launching process
    def on_multirun_start(self, config, **kwargs):
        total = count_jobs(config)
        fd, name = tempfile.mkstemp(prefix="psbench-sweep-", suffix=".jsonl")
        head = dict(header=True, total=total, t0=time.time(), sweep=str(config.get("sweep")))
        os.write(fd, (json.dumps(head) + "\n").encode())
        os.close(fd)
        self.path = name
        _PENDING.add(name)
        atexit.register(_remove, name)       # also when the sweep is interrupted

    def on_multirun_end(self, config, **kwargs):
        if not self.path:
            return
        try:
            head, recs = _read(self.path)
            _finish(head, recs, config)
        finally:
            _remove(self.path)

    # ------------------------------------------------------------------ job processes
    def on_job_end(self, config, job_return, **kwargs):
        if not self.path or not os.path.exists(self.path):
            return
        from hydra.core.utils import JobStatus

        rv = job_return.return_value if job_return.status == JobStatus.COMPLETED else None
        rec = dict(rv) if isinstance(rv, dict) else {}
        if job_return.status != JobStatus.COMPLETED:
            rec["status"] = "failed"
        rec["overrides"] = list(job_return.overrides or [])
        try:
            rec["num"] = int(config.hydra.job.num)      # the job's place in the sweep
        except Exception:  # noqa: BLE001
            rec["num"] = None
        line = (json.dumps(rec, default=str) + "\n").encode()
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            os.write(fd, line)           # one write per line: appends do not interleave
        finally:
            os.close(fd)
        head, recs = _read(self.path)
        total = head.get("total")
        done = len(recs)
        failed = sum(r.get("status") == "failed" for r in recs)
        el = time.time() - float(head.get("t0", time.time()))
        eta = el / done * (total - done) if total and done else None
        fail = f", {failed} failed" if failed else ""
        print(f"sweep {head.get('sweep', '')}: {done}/{total or '?'} done{fail} | elapsed "
              f"{_hms(el)} | ETA {_hms(eta)}", file=sys.stderr, flush=True)


_PENDING: set = set()


def _remove(path):
    _PENDING.discard(path)
    try:
        os.unlink(path)
    except OSError:
        pass


def cleanup():
    """Remove the progress files of sweeps of this process (for interrupt handlers that
    leave without running ``atexit``)."""
    for p in list(_PENDING):
        _remove(p)


def _finish(head, recs, config):
    """Summary table (stdout) and comparison sheet of the finished sweep."""
    from .outputs import MARKER
    from .store import read_run

    rows, runs = [], []
    recs = sorted(recs, key=lambda r: (r.get("num") is None, r.get("num") or 0))
    for rec in recs:                       # in the sweep's order (the sheet's columns)
        rid, root, sweep = rec.get("run_id"), rec.get("root"), rec.get("sweep")
        if not (rid and root and sweep):
            continue
        row = read_run(root, sweep, rid)
        if row is None:
            continue
        row = dict(row)
        rows.append(row)
        if rec.get("out") and (Path(rec["out"]) / MARKER).is_file():
            runs.append((row, Path(rec["out"])))
    name = head.get("sweep") or ""
    if not rows:
        print(f"sweep {name}: no stored runs to summarise", flush=True)
        return
    axes = varying(rows)
    print(f"\nsweep {name}: {len(rows)} runs, best first (NE: mean angular error; IE: L2 "
          "Lambert residual in % of the images' dynamic range)", flush=True)
    print(summary_table(rows, axes), flush=True)
    dirs = {p.parent for _, p in runs}
    if not runs or len(dirs) != 1:
        return
    from .sheet import build_sheet

    try:
        png, html = build_sheet([(r, p) for r, p in runs], dirs.pop(), axes=axes,
                                title=f"psbench sweep {name}")
    except Exception as exc:  # noqa: BLE001 - the rows are stored; say what failed
        print(f"psbench: warning: comparison sheet not written: {type(exc).__name__}: {exc}",
              file=sys.stderr, flush=True)
        return
    print(f"comparison sheet: {html} (picture {png.name}); pictures of each run in "
          f"{png.parent}/<run_id>/", flush=True)
