"""Chunked and sharded execution of many runs (experiments).

- :func:`plan` drops runs already stored (unless ``rerun``; failed ones are retried
  with ``retry_failed``).
- :func:`make_chunks` groups runs that share a scene (one render per chunk) and packs
  small groups together.
- :func:`execute_runs` runs chunks with joblib in this machine's cores
  (``launcher="joblib"``) or submits shards with submitit (``submitit_local``,
  ``submitit_slurm``, ``submitit_debug``); each shard runs its chunks in-process and
  writes per-run files, so a killed or partial execution resumes where it stopped.
"""
from __future__ import annotations

import contextlib
import math
import os
import time
from pathlib import Path

from .._shared.checks import PsbenchError
from .params import run_id, scene_key
from .progress import Progress
from .spec import LAUNCHERS, RUN_KINDS
from .store import default_root, stored_status
from .supervise import run_supervised, worker_setup

__all__ = ["LAUNCHERS", "plan", "make_chunks", "split_shards", "run_shard", "execute_runs"]


def plan(runs, *, root, sweep, rerun=False, retry_failed=False):
    """Split normalized runs into (todo, skipped) given what the store holds."""
    if rerun:
        return list(runs), []
    stored = stored_status(root, sweep)
    todo, skipped = [], []
    for p in runs:
        st = stored.get(run_id(p, root=root))
        if st == "ok" or (st is not None and not retry_failed):
            skipped.append(p)
        else:
            todo.append(p)
    return todo, skipped


def make_chunks(runs, *, workers=1, target=None):
    """Group runs by scene (never split a group) and pack small groups into chunks of
    about ``target`` runs (default: total / (4 * workers), between 1 and 16).

    Only solves share a scene: analysis, ``cond`` and plug-in runs are groups of one
    (in the given order), so that runs of one analysis with equal scene parameters
    still spread over the workers.
    """
    groups = {}
    for i, p in enumerate(runs):
        key = scene_key(p)
        if p.get("kind") in _UNSHARED or p.get("kind") not in RUN_KINDS:
            key += (f"{i:09d}",)
        groups.setdefault(key, []).append(p)
    if target is None:
        target = max(1, min(16, math.ceil(len(runs) / (4 * max(1, workers)))))
    chunks, cur = [], []
    for key in sorted(groups):
        cur.extend(groups[key])
        if len(cur) >= target:
            chunks.append(cur)
            cur = []
    if cur:
        chunks.append(cur)
    return chunks


#: run kinds that render no scene of their own to share
_UNSHARED = ("analysis", "cond")


def split_shards(chunks, shards):
    """Distribute chunks over ``shards`` lists, balancing the number of runs."""
    shards = max(1, int(shards))
    out = [[] for _ in range(shards)]
    load = [0] * shards
    for c in sorted(chunks, key=len, reverse=True):
        i = load.index(min(load))
        out[i].append(c)
        load[i] += len(c)
    return [s for s in out if s]


def run_shard(chunks, *, root, sweep, experiment=None, jobs=1):
    """A shard job's body: run chunks in this job (``jobs`` joblib workers, 1 = in-process)."""
    if _n_workers(jobs) == 1 or len(chunks) == 1:
        out = []
        for c in chunks:
            out.extend(_summaries(run_supervised(c, root=root, sweep=sweep,
                                                 experiment=experiment)))
        return out
    prog = Progress(sum(len(c) for c in chunks), label=sweep, stream=open(os.devnull, "w"))
    return _joblib(chunks, prog, jobs=jobs, root=root, sweep=sweep, experiment=experiment)


def _summaries(rows):
    return [{k: r.get(k) for k in ("run_id", "status", "error", "t_total")} for r in rows]


def _pool_chunk(chunk, root, sweep, experiment, main_pid):
    """A pool worker's task: follow the main process, then run the chunk supervised."""
    worker_setup(main_pid)
    return _summaries(run_supervised(chunk, root=root, sweep=sweep, experiment=experiment))


def _n_workers(jobs):
    try:
        n = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    # inside a SLURM job whose CPUs are not pinned (TaskPlugin=task/none): its allocation
    if os.environ.get("SLURM_CPUS_ON_NODE", "").isdigit():
        n = max(1, min(n, int(os.environ["SLURM_CPUS_ON_NODE"])))
    jobs = int(jobs)
    return n if jobs == -1 else max(1, n + 1 + jobs if jobs < 0 else jobs)


#: pool restarts after a worker process itself was lost, before giving up
POOL_RESTARTS = 3


def _joblib(chunks, prog, *, jobs, root, sweep, experiment):
    results = []
    if _n_workers(jobs) == 1 or len(chunks) == 1:
        for c in chunks:
            res = _summaries(run_supervised(c, root=root, sweep=sweep, experiment=experiment))
            prog.update(len(res), sum(r["status"] != "ok" for r in res))
            results.extend(res)
        return results
    from joblib import Parallel, delayed

    pending = list(chunks)
    for attempt in range(POOL_RESTARTS + 1):
        par = Parallel(n_jobs=int(jobs), return_as="generator_unordered")
        try:
            for res in par(delayed(_pool_chunk)(c, str(root), sweep, experiment, os.getpid())
                           for c in pending):
                prog.update(len(res), sum(r["status"] != "ok" for r in res))
                results.extend(res)
            return results
        except Exception as exc:  # noqa: BLE001 - a worker process itself was killed
            from .params import run_id

            got = {r["run_id"] for r in results}
            stored = stored_status(root, sweep)
            for c in pending:            # stored by the lost pool: counted, not redone
                for rid in (run_id(p, root=root) for p in c):
                    if rid in stored and rid not in got:
                        got.add(rid)
                        results.append({"run_id": rid, "status": stored[rid], "error": None,
                                        "t_total": None})
                        prog.update(1, stored[rid] != "ok")
            seen = got | set(stored)
            pending = [[p for p in c if run_id(p, root=root) not in seen] for c in pending]
            pending = [c for c in pending if c]
            lost = f"{type(exc).__name__}: {str(exc).splitlines()[0][:200] if str(exc) else ''}"
            if not pending:
                return results
            if attempt == POOL_RESTARTS:
                prog.stream.write(f"\nworker pool lost {attempt + 1} times ({lost}); completed "
                                  "runs are stored: run the same command again to resume\n")
                failed = [{"run_id": run_id(p, root=root), "status": "failed", "error": lost,
                           "t_total": None} for c in pending for p in c]
                prog.update(len(failed), len(failed))   # the summary counts them too
                results.extend(failed)
                return results
            prog.stream.write(f"\na worker process was lost ({lost}); restarting the pool "
                              f"for the {sum(map(len, pending))} runs not stored\n")
    return results


def _executor(launcher, folder, params):
    import submitit

    if launcher == "submitit_local":
        ex = submitit.LocalExecutor(folder=str(folder))
    elif launcher == "submitit_debug":
        ex = submitit.DebugExecutor(folder=str(folder))
    else:
        ex = submitit.AutoExecutor(folder=str(folder), cluster="slurm")
    params = {k: v for k, v in dict(params or {}).items() if v is not None}
    if launcher != "submitit_slurm":
        params = {k: v for k, v in params.items() if k in ("timeout_min",)}
    if params:
        ex.update_parameters(**params)
    return ex


def _written(root, sweep, ids, since):
    """How many of the runs ``ids`` have a per-run file written since ``since``."""
    from .store import run_path

    n = 0
    for rid in ids:
        try:
            n += run_path(root, sweep, rid).stat().st_mtime >= since
        except OSError:
            pass
    return n


#: SLURM job states in which a job may still write its result
_SLURM_ACTIVE = frozenset({"PENDING", "CONFIGURING", "RUNNING", "COMPLETING", "SUSPENDED",
                           "REQUEUED", "REQUEUE_HOLD", "REQUEUE_FED", "RESIZING", "STAGE_OUT",
                           "SIGNALING", "PREEMPTED", "RESV_DEL_HOLD", "SPECIAL_EXIT"})
#: seconds a SLURM job may have ended before its result file must be visible
_SLURM_GRACE_S = 30.0


def _slurm_ended(job_ids):
    """``{job_id: state}`` of the jobs among ``job_ids`` that SLURM no longer runs or
    queues, asked from ``squeue`` (``sacct``, which submitit polls, fails on clusters
    without an accounting database); None when squeue cannot tell."""
    import subprocess

    try:
        p = subprocess.run(["squeue", "-h", "-o", "%i %T", "--states=all", "-j",
                            ",".join(job_ids)], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return None
    if p.returncode != 0:                   # all purged from the controller, or no answer
        return dict.fromkeys(job_ids, "GONE") if "Invalid job id" in p.stderr else None
    states = dict(ln.split(None, 1) for ln in p.stdout.splitlines() if " " in ln.strip())
    return {i: states.get(i, "GONE").strip() for i in job_ids
            if states.get(i, "GONE").strip().upper() not in _SLURM_ACTIVE}


def _submitit(chunks, prog, *, launcher, shards, root, sweep, experiment, folder, params, wait,
              jobs=1):
    shard_lists = split_shards(chunks, shards)
    ex = _executor(launcher, folder, params)
    ids = [run_id(p, root=root) for c in chunks for p in c]
    since = time.time() - 1.0
    jobs = [ex.submit(run_shard, s, root=str(root), sweep=sweep, experiment=experiment,
                      jobs=jobs) for s in shard_lists]
    jids = ", ".join(str(j.job_id) for j in jobs)   # (not `ids`: the store poll uses them)
    prog.stream.write(f"submitted {len(jobs)} shard job(s) with {launcher} ({jids}); logs in "
                      f"{folder}\n")
    if not wait:
        return None
    results, pending = [], list(jobs)
    last_poll = last_queue = 0.0
    # SLURM: a job is done when its result file exists and lost when squeue says it ended
    # without one (submitit's own check needs sacct and would wait forever without it)
    slurm, ended = launcher == "submitit_slurm", {}
    try:
        while pending:
            if time.time() - last_poll > 2.0:          # progress from the store, run by run
                last_poll = time.time()
                n = _written(root, sweep, ids, since)
                if n > prog.done:
                    prog.update(n - prog.done)
            if slurm and time.time() - last_queue > 10.0:
                last_queue = time.time()
                for jid, state in (_slurm_ended([str(j.job_id) for j in pending]) or {}).items():
                    ended.setdefault(jid, (last_queue, state))
            for j in list(pending):
                lost = None
                if slurm:
                    finished = j.paths.result_pickle.exists()
                    t_end, state = ended.get(str(j.job_id), (None, None))
                    if not finished and t_end is not None and time.time() - t_end > _SLURM_GRACE_S:
                        lost = f"ended ({state}) without a result; logs in {j.paths.folder}"
                else:
                    finished = j.done()
                if finished or lost:
                    pending.remove(j)
                    try:
                        if lost:
                            raise RuntimeError(lost)
                        res = j.result()
                    except Exception as exc:  # noqa: BLE001 - a lost shard is reported, not fatal
                        msg = f"shard job {j.job_id} failed: {type(exc).__name__}: {str(exc)[:500]}"
                        prog.stream.write(msg + "; its stored runs are kept: run the same command "
                                          "again to resume\n")
                        # counted as failed (exit 1): the grid is not complete
                        results.append({"run_id": None, "status": "failed", "error": msg,
                                        "t_total": None})
                        continue
                    results.extend(res)
                    n_done = len(results)
                    prog.failed = sum(r["status"] != "ok" for r in results)
                    if n_done > prog.done:
                        prog.update(n_done - prog.done)
            if pending:
                time.sleep(0.5)
    except KeyboardInterrupt:
        if launcher != "submitit_slurm":     # local jobs are this machine's: stop them too
            for j in pending:
                with contextlib.suppress(Exception):
                    j.cancel(check=False)
        raise
    return results


def execute_runs(runs, *, root, sweep, experiment=None, rerun=False, retry_failed=False,
                 jobs=-1, launcher="joblib", shards=1, submitit=None, stream=None,
                 label=None):
    """Plan, chunk and execute runs; returns a summary dict.

    Returns
    -------
    dict
        ``total``, ``skipped``, ``ok``, ``failed`` counts and ``results`` (per-run dicts)
        (``results`` is None when shard jobs were submitted without waiting).
    """
    if launcher not in LAUNCHERS:
        raise PsbenchError(f"launcher={launcher!r} is not known; valid choices: {', '.join(LAUNCHERS)}")
    root = default_root(root)
    todo, skipped = plan(runs, root=root, sweep=sweep, rerun=rerun, retry_failed=retry_failed)
    if todo:                       # configuration errors: refused before any work
        from .preflight import preflight

        preflight(todo, root=root, sweep=sweep)
    prog = Progress(len(todo), label=label or sweep, stream=stream, skipped=len(skipped))
    if skipped:
        prog.stream.write(f"{sweep}: {len(skipped)} of {len(runs)} runs skipped (stored)"
                          f"{'' if retry_failed else '; retry_failed=true retries failed ones'}\n")
    results = []
    if todo:
        if launcher == "joblib":
            if all(p["kind"] == "cond" for p in todo):
                jobs = 1                  # microseconds each: worker start-up would dominate
            chunks = make_chunks(todo, workers=_n_workers(jobs))
            results = _joblib(chunks, prog, jobs=jobs, root=root, sweep=sweep,
                              experiment=experiment)
        else:
            sub = dict(submitit or {})
            folder = Path(sub.pop("folder", None) or (root / "submitit")) / "%j"
            wait = bool(sub.pop("wait", True))
            chunks = make_chunks(todo, workers=max(1, int(shards)))
            results = _submitit(chunks, prog, launcher=launcher, shards=shards, root=root,
                                sweep=sweep, experiment=experiment, folder=folder,
                                params=sub, wait=wait,
                                # local shards share this machine: one process each
                                jobs=1 if launcher != "submitit_slurm" and jobs == -1 else jobs)
    prog.close()
    ok = None if results is None else sum(r["status"] == "ok" for r in results)
    failed = None if results is None else sum(r["status"] != "ok" for r in results)
    return dict(total=len(runs), skipped=len(skipped), todo=len(todo), ok=ok, failed=failed,
                results=results)
