"""Runs in a supervised child process; workers that follow their parent.

Every run (a single ``psbench`` call, a ``-m`` job, an experiment chunk, a shard) is
computed in a child process forked for its chunk, while the process that forked it
only waits. When the child dies -- killed by the out-of-memory killer (the child asks
to be its first choice), a ``MemoryError`` that leaves no room to write, a segfault --
the supervisor writes the run's row as failed with the cause and the chunk goes on
with its next run; a sweep is never lost with its worker. The child dies with its
supervisor (``PR_SET_PDEATHSIG`` on Linux), and a worker process of a pool exits
within a second when the process that started it is gone (:func:`watch_parent`), so a
killed ``psbench -m`` leaves no orphans writing on.

Elsewhere than on Linux (or with ``PSBENCH_INPROCESS=1``) runs are computed in the
calling process.
"""
from __future__ import annotations

import contextlib
import os
import pickle
import signal
import struct
import sys
import threading
import time

from .._shared.checks import PsbenchError

__all__ = ["run_supervised", "watch_parent", "worker_setup", "MAIN_PID_ENV"]

#: environment variable holding the pid of the ``psbench`` process that started a sweep
MAIN_PID_ENV = "PSBENCH_MAIN_PID"
_CHILD = {"pid": None}
_STOP = (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", signal.SIGTERM))
_WATCHING = {"on": False}


# ---------------------------------------------------------------------------- OS helpers
def _prctl_pdeathsig(sig=signal.SIGKILL) -> bool:
    """Ask Linux to send ``sig`` to this process when its parent exits."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(1, int(sig), 0, 0, 0) == 0       # PR_SET_PDEATHSIG = 1
    except (OSError, AttributeError):
        return False


def _first_oom_victim():
    """Make this (run) process the out-of-memory killer's first choice, so that it, not
    the supervisor or the sweep's main process, is killed when memory runs out."""
    with contextlib.suppress(OSError):
        with open("/proc/self/oom_score_adj", "w") as fh:
            fh.write("1000")


def watch_parent(parent_pid=None, *, interval=0.5) -> bool:
    """In a worker process of a pool: exit (killing the run child it supervises) as
    soon as ``parent_pid`` (default: the current parent) is no longer the parent.

    Returns False when not installed (already watching, or not a child of
    ``parent_pid``)."""
    parent_pid = os.getppid() if parent_pid is None else int(parent_pid)
    if _WATCHING["on"] or os.getppid() != parent_pid:
        return False
    _WATCHING["on"] = True

    def watch():
        while True:
            time.sleep(interval)
            if os.getppid() != parent_pid:
                child = _CHILD["pid"]
                if child:
                    with contextlib.suppress(OSError):
                        os.kill(child, signal.SIGKILL)
                os._exit(1)

    threading.Thread(target=watch, name="psbench-parent-watch", daemon=True).start()
    return True


def worker_setup(main_pid) -> None:
    """Set up a pool worker started by the ``psbench`` process ``main_pid``: follow it
    when it dies, and leave Ctrl-C to it (it stops the pool and reports)."""
    from .._shared.warn import install

    install()                        # warnings as one psbench line each, as in the main
    if main_pid is None or int(main_pid) == os.getpid():
        return
    if os.environ.get("SUBMITIT_LOCAL_JOB_ID") or os.environ.get("SLURM_JOB_ID"):
        return                       # a scheduler's job, not a pool worker
    if os.getppid() != int(main_pid) and os.getppid() == 1:
        os._exit(1)                  # started before the main process died: nothing to do
    if watch_parent(int(main_pid)) and threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def _can_fork() -> bool:
    # Linux only: fork after BLAS / GUI frameworks have started threads is unsafe on
    # macOS, and PR_SET_PDEATHSIG is Linux's
    return (sys.platform.startswith("linux") and hasattr(os, "fork")
            and os.environ.get("PSBENCH_INPROCESS", "") in ("", "0"))


# ---------------------------------------------------------------------------- messages
def _send(fd, obj):
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    view = memoryview(struct.pack("<Q", len(data)) + data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def _recv_all(fd):
    """Messages until EOF (a partial last message -- the child died writing -- is dropped)."""
    buf = bytearray()
    while True:
        chunk = os.read(fd, 1 << 16)
        if not chunk:
            break
        buf += chunk
        while len(buf) >= 8:
            n = struct.unpack("<Q", buf[:8])[0]
            if len(buf) < 8 + n:
                break
            yield pickle.loads(bytes(buf[8:8 + n]))
            del buf[:8 + n]


def _death(status) -> str:
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        name = signal.Signals(sig).name if sig in signal.Signals._value2member_map_ else sig
        why = " (out of memory? the kernel's OOM killer sends it)" if sig == signal.SIGKILL else ""
        return f"the run's process was killed by {name}{why}"
    return f"the run's process exited with status {os.WEXITSTATUS(status)} before storing its row"


def _clean_temps(root, sweep, pid):
    """Remove the temporary files of a (reaped, so dead) child."""
    from .store import default_root

    d = default_root(root) / "runs" / sweep
    for p in d.glob(f".*.tmp.{pid}.*") if d.is_dir() else ():
        with contextlib.suppress(OSError):
            p.unlink()


# ---------------------------------------------------------------------------- supervision
def run_supervised(chunk, *, root, sweep, experiment=None, config=None, wrap=None,
                   after=None):
    """Run normalized parameter dicts (a chunk sharing scenes) and store each row.

    Parameters
    ----------
    chunk : list of dict
        Normalized run parameters.
    root, sweep, experiment, config
        Where and how the rows are stored (:func:`psbench.harness.run.execute`).
    wrap : callable, optional
        Context manager factory entered around each run in the process computing it
        (e.g. to show warnings as one line).
    after : callable, optional
        ``after(row, kept) -> str or None`` called in the process that computed a run,
        after it and before its row is stored (``kept``: the solve's ``result`` and
        ``scene``, see ``execute(keep=)``), e.g. to write the run's pictures; what it
        returns comes back as the row's ``_note``. It must not raise.

    Returns
    -------
    list of dict
        The stored rows (with ``exc_kind``: None, ``"config"`` for a PsbenchError,
        ``"memory"``, ``"error"`` otherwise, ``"killed"`` when the process died).

    Raises
    ------
    KeyboardInterrupt
        On Ctrl-C, after the child is gone and its temporary files are removed.
    """
    from .params import run_id, scene_key

    todo = sorted(chunk, key=scene_key)
    if not _can_fork():
        return [_run_one(p, root, sweep, experiment, config, {}, wrap, after)[0] for p in todo]
    out = []
    while todo:
        rows, started, status = _fork(todo, root, sweep, experiment, config, wrap, after)
        out.extend(rows)
        done = {r["run_id"] for r in rows}
        todo = [p for p in todo if run_id(p, root=root) not in done]
        if status is None or not todo:
            continue
        if (os.WIFEXITED(status) and os.WEXITSTATUS(status) == 130) or (
                os.WIFSIGNALED(status) and os.WTERMSIG(status) in _STOP):
            raise KeyboardInterrupt            # stopped by the user, not a failed run
        culprit = next((p for p in todo if run_id(p, root=root) == started), todo[0])
        row = _failed(culprit, _death(status), root, sweep, experiment, config)
        out.append(row)
        todo = [p for p in todo if p is not culprit]
    return out


def _failed(p, error, root, sweep, experiment, config):
    from .run import failed_row
    from .store import write_row

    row = failed_row(p, error, sweep=sweep, experiment=experiment, config=config, root=root)
    write_row(root, row)
    row["exc_kind"] = "killed"
    return row


def _row_to_store(row):
    return {k: v for k, v in row.items() if k != "exc_kind" and not k.startswith("_")}


def _run_one(p, root, sweep, experiment, config, cache, wrap, after, *, tolerant=False):
    """Compute run ``p`` here and store its row; returns (row, stored). With
    ``tolerant``, a store write failing for lack of memory returns ``stored=False``
    (the supervisor writes it) instead of raising."""
    from .run import execute
    from .store import write_row

    kept = {} if after is not None else None
    with (wrap() if wrap is not None else contextlib.nullcontext()):
        row = execute(p, sweep=sweep, experiment=experiment, cache=cache, config=config,
                      keep=kept, root=root)
    row["exc_kind"] = _kind(row.pop("_exc", None))
    if after is not None:
        row["_note"] = after(row, kept)    # before the row: stored "ok" => its outputs
        kept.clear()
    try:
        write_row(root, _row_to_store(row))
    except MemoryError:
        if not tolerant:
            raise
        return row, False
    except Exception as err:  # noqa: BLE001 - e.g. pyarrow's ArrowMemoryError
        if not tolerant or "memory" not in type(err).__name__.lower():
            raise
        return row, False
    return row, True


def _kind(exc):
    """How a run failed: None (it did not), "config" (a PsbenchError), "memory" (the
    environment ran out of memory) or "error" (a bug or a numerical failure)."""
    if exc is None:
        return None
    if isinstance(exc, PsbenchError):
        return "config"
    if isinstance(exc, MemoryError) or "memory" in type(exc).__name__.lower():
        return "memory"
    return "error"


def _fork(todo, root, sweep, experiment, config, wrap=None, after=None):
    """One child for ``todo``: (rows it stored, run_id it was running, exit status or
    None when it finished every run)."""
    for stream in (sys.stdout, sys.stderr):   # or the child would print them again
        with contextlib.suppress(Exception):
            stream.flush()
    r, w = os.pipe()
    parent = os.getpid()
    cv_threads = _opencv_pool_stopped()
    try:
        pid = os.fork()
    except BaseException:
        _opencv_threads(cv_threads)
        raise
    if pid == 0:                               # ---- the child
        os.close(r)
        code = 1
        try:
            _opencv_threads(cv_threads)        # a pool of its own
            _prctl_pdeathsig()
            if os.getppid() != parent:
                os._exit(1)
            _first_oom_victim()
            _child(todo, w, root, sweep, experiment, config, wrap, after)
            code = 0
        except KeyboardInterrupt:
            code = 130
        except BaseException:  # noqa: BLE001 - reported by the supervisor as a death
            code = 1
        finally:
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    stream.flush()
            os._exit(code)
    os.close(w)                                # ---- the supervisor
    _opencv_threads(cv_threads)
    _CHILD["pid"] = pid
    rows, started, status = [], None, None
    try:
        for msg in _recv_all(r):
            if msg[0] == "start":
                started = msg[1]
            else:
                row, stored = msg[1], msg[2]
                if not stored:                 # the child could not write (memory)
                    from .store import write_row

                    write_row(root, _row_to_store(row))
                rows.append(row)
                started = None
        status = os.waitpid(pid, 0)[1]
    except BaseException:
        with contextlib.suppress(OSError):
            os.kill(pid, signal.SIGKILL)
        with contextlib.suppress(OSError):
            os.waitpid(pid, 0)
        _clean_temps(root, sweep, pid)
        raise
    finally:
        os.close(r)
        _CHILD["pid"] = None
    if status == 0 and started is None:
        return rows, None, None
    _clean_temps(root, sweep, pid)
    return rows, started, status


def _opencv_pool_stopped():
    """Stop OpenCV's worker threads before a fork; returns the thread count to restore
    (None where OpenCV is not loaded: its pool cannot have started).

    A child forked while OpenCV's pool has threads inherits a pool whose threads do
    not exist in it, and its next parallel call (``cv2.warpAffine`` of the shadow
    maps) can wait for them forever: measured, 2 of 300 forks hung, and a 6-run
    sweep hung in a fresh-clone test run. With the pool stopped (one thread joins its
    workers) the child starts a pool of its own: 0 of 300."""
    cv2 = sys.modules.get("cv2")
    if cv2 is None or not hasattr(cv2, "setNumThreads"):
        return None
    n = cv2.getNumThreads()
    cv2.setNumThreads(1)
    return n


def _opencv_threads(n):
    if n is not None and n != 1:
        sys.modules["cv2"].setNumThreads(n)


def _child(todo, w, root, sweep, experiment, config, wrap, after):
    from .params import run_id

    cache = {}
    for p in todo:
        _send(w, ("start", run_id(p, root=root)))
        row, stored = _run_one(p, root, sweep, experiment, config, cache, wrap, after,
                               tolerant=True)
        _send(w, ("row", row, stored))
