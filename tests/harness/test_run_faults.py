"""Runs under faults: a killed sweep parent, a killed run process, Ctrl-C, a read-only
store, a memory limit, and launch-independent numbers (issue 11 S2-S5, C2, D1; issue
12 item 3). Subprocesses at tiny sizes; ``kind=noop`` runs where the numbers do not
matter."""
import contextlib
import os
import resource
import shutil
import signal
import subprocess
import sys
import time

import pytest

from psbench.harness import store
from psbench.harness.grid import expand
from psbench.harness.shards import execute_runs

psutil = pytest.importorskip("psutil")

from _cli import CMD, communicate, run_psbench  # noqa: E402
from _cli import clean_env as _env  # noqa: E402

METRICS = ["ne_mean", "ne_median", "ne_lt5", "ne_lt10", "ne_lt20", "ie_l1", "ie_l2", "ie_linf",
           "ie_rel", "qf_hi", "qf_sh", "qf_total"]


def psbench(*args, cwd, timeout=240, **kw):
    return run_psbench(*args, cwd=cwd, timeout=timeout, **kw)


def _no_traceback(*texts):
    for t in texts:
        assert "Traceback" not in t and "KeyboardInterrupt" not in t, t[-2000:]


def _busy_workers(pid, at_least=1):
    """The pool workers of process ``pid`` that are computing a run, when there are
    ``at_least`` that many (else []): its direct children with a run process of their
    own (a worker forks one per job once it has set itself up; the resource trackers,
    also children, have none)."""
    busy = []
    with contextlib.suppress(psutil.Error):
        for w in psutil.Process(pid).children():
            with contextlib.suppress(psutil.Error):
                if w.children():
                    busy.append(w)
    return busy if len(busy) >= at_least else []


def _sigint_default():
    """In the child: SIGINT's default action, even when the tests run with it ignored
    (a background job of a non-interactive shell inherits SIGINT ignored, and an
    ignored signal is discarded before psbench could see it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _until(cond, what, timeout=180.0):
    """Poll ``cond()`` until it returns something true; the timeout only bounds a hang."""
    t0 = time.time()
    while time.time() - t0 < timeout:
        got = cond()
        if got:
            return got
        time.sleep(0.05)
    raise AssertionError(f"{what}: not within {timeout:.0f} s")


# a plug-in experiment of noop runs (installed as pip would: a *.dist-info on the path),
# so an experiment's pool is exercised in seconds
_EXP_MODULE = '''"""Noop runs that sleep: an experiment that is still computing when stopped."""
TITLE = "sleeping noop runs"


def aggregate(rows):
    return rows
'''
_EXP_GRID = """experiment:
  name: sleepy
  grids:
    - {kind: [noop], seed: [0, 1, 2, 3], args: {sleep: 60}}
  scales:
    full: {}
    ci: {}
"""


def _sleepy_experiment(tmp_path):
    """Install experiment ``sleepy`` under ``tmp_path``; returns the environment that sees it."""
    site = tmp_path / "site"
    (site / "psbsleepy").mkdir(parents=True)
    (site / "psbsleepy" / "__init__.py").write_text("")
    (site / "psbsleepy" / "sleepy.py").write_text(_EXP_MODULE)
    (site / "psbsleepy" / "sleepy.yaml").write_text(_EXP_GRID)
    info = site / "psbsleepy-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: psbsleepy\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[psbench.experiments]\nsleepy = psbsleepy.sleepy\n")
    env = _env()
    env["PYTHONPATH"] = os.pathsep.join([str(site)] + [p for p in
                                        [env.get("PYTHONPATH")] if p])
    return env


def test_killed_sweep_parent_leaves_no_worker(tmp_path):
    """S2: SIGKILL of ``psbench -m``'s process: its pool workers and their run
    processes exit within a few seconds."""
    proc = subprocess.Popen(CMD + ["-m", "kind=noop", "seed=0,1,2,3", "args.sleep=60",
                                   f"results_dir={tmp_path}", "hydra.launcher.n_jobs=2"],
                            cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        # both workers computing a run (so both have set up to follow their parent)
        workers = _until(lambda: _busy_workers(proc.pid, 2), "both pool workers computing a run")
        kids = workers + [k for w in workers for k in w.children(recursive=True)]
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=60)
        t = time.time()
        gone, alive = psutil.wait_procs(kids, timeout=15)
        assert not alive, f"still running {time.time() - t:.1f} s after: {alive}"
    finally:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
    assert not store.temp_files(tmp_path) or all(store.dead_temp(p, grace=0)
                                                 for p in store.temp_files(tmp_path))


def test_killed_run_is_stored_failed_and_the_sweep_completes(tmp_path):
    """S3: a run process killed (as by the OOM killer): that run is stored as failed
    with the cause, every other run of the ``-m`` sweep completes."""
    r = psbench("-m", "kind=noop", "seed=0,1", "args.die=false,true", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    _no_traceback(r.stderr)
    df = store.read_store(tmp_path / "results")
    assert len(df) == 4 and df["run_id"].is_unique
    died = df[df["status"] == "failed"]
    assert len(died) == 2 and died["error"].str.contains("killed by SIGKILL").all()
    assert died["args"].str.contains('"die": true').all()


def test_killed_run_in_an_experiment_pool(tmp_path):
    runs = expand({"name": "e", "grids": [{"kind": "noop", "seed": [0, 1, 2, 3, 4, 5]},
                                          {"kind": "noop", "seed": 9, "args": {"die": True}}]})
    out = execute_runs(runs, root=tmp_path, sweep="e", experiment="e", jobs=2,
                       stream=open(os.devnull, "w"))
    assert out["ok"] == 6 and out["failed"] == 1
    df = store.read_store(tmp_path)
    assert len(df) == 7 and (df["status"] == "failed").sum() == 1
    assert "killed by SIGKILL" in df.loc[df["status"] == "failed", "error"].iloc[0]


def test_same_run_single_and_in_a_sweep_bit_identical(tmp_path):
    """D1: one BLAS thread everywhere: ``psbench`` and a ``psbench -m`` worker store
    the very same numbers for the same run."""
    args = ["size=48", "lights=30x8+60x8", "weighted=true", "outputs=none"]
    a = psbench(*args, "mask=Th-Hi-Re-Sh", f"results_dir={tmp_path / 'a'}", cwd=tmp_path)
    assert a.returncode == 0, a.stderr
    b = psbench("-m", *args, "mask=Th-Hi-Re-Sh,Th", f"results_dir={tmp_path / 'b'}",
                cwd=tmp_path)
    assert b.returncode == 0, b.stderr
    ra = store.read_store(tmp_path / "a").set_index("run_id")
    rb = store.read_store(tmp_path / "b").set_index("run_id").loc[ra.index]
    for c in METRICS:
        assert (ra[c] == rb[c]).all() or (ra[c].isna() & rb[c].isna()).all(), c


def test_runs_compute_with_one_blas_thread(monkeypatch):
    threadpoolctl = pytest.importorskip("threadpoolctl")
    from psbench.harness import run as R

    seen = []
    monkeypatch.setattr(R, "_compute", lambda p, row, cache, keep=None: seen.extend(
        i["num_threads"] for i in threadpoolctl.threadpool_info() if i["user_api"] == "blas"))
    with threadpoolctl.threadpool_limits(limits=2):
        row = R.execute(R.normalize({"kind": "noop"}))
    assert row["status"] == "ok" and seen and set(seen) == {1}


@pytest.mark.parametrize("args", [["-m", "kind=noop", "seed=0,1,2,3", "args.sleep=60",
                                   "hydra.launcher.n_jobs=2"],
                                  ["kind=noop", "args.sleep=60"],
                                  ["+experiment=sleepy", "scale=ci", "jobs=2"]],
                         ids=["sweep", "run", "experiment"])
def test_ctrl_c_one_line_no_traceback_no_temp(tmp_path, args):
    """Issue 12 item 3: Ctrl-C (SIGINT to the process group) of a sweep, a run or an
    experiment, while its runs compute: one line, exit 130, no traceback, no temporary
    file, and no run stored (none had finished)."""
    pool = "-m" in args or any(a.startswith("+experiment") for a in args)
    env = _sleepy_experiment(tmp_path) if pool and "-m" not in args else _env()
    proc = subprocess.Popen(CMD + args + [f"results_dir={tmp_path}"], cwd=tmp_path,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True, preexec_fn=_sigint_default)
    try:
        # until every pool worker computes a run (a worker still starting up has Python's
        # own SIGINT handler for a moment), or the single run's process is forked
        if pool:
            _until(lambda: proc.poll() is not None or _busy_workers(proc.pid, 2),
                   "both pool workers computing")
        else:
            _until(lambda: proc.poll() is not None or psutil.Process(proc.pid).children(),
                   "the run's process started")
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 130, err
    _no_traceback(out, err)
    lines = [ln for ln in err.splitlines() if ln.startswith("interrupted")]
    assert len(lines) == 1 and lines[0].endswith("stored; run the same command to resume")
    assert lines[0].startswith("interrupted: 0/"), lines[0]
    assert not store.temp_files(tmp_path)


def _readonly_cmd(store_dir, args):
    """The command run with ``store_dir`` read-only: a read-only bind mount (root, in a
    private mount namespace) or permission bits (other users)."""
    if os.geteuid() != 0:
        os.chmod(store_dir, 0o555)
        return CMD + args
    unshare = shutil.which("unshare")
    if unshare is None or subprocess.run([unshare, "-m", "true"], capture_output=True).returncode:
        pytest.skip("running as root without mount namespaces: cannot make a read-only store")
    q = " ".join(f"'{a}'" for a in CMD + args)
    return [unshare, "-m", "sh", "-c",
            f"mount --bind -o ro '{store_dir}' '{store_dir}' && exec {q}"]


def test_read_only_store_refused_before_computing(tmp_path):
    """C2 / S4: one line, exit 2, nothing computed."""
    res = tmp_path / "ro"
    res.mkdir()
    r = subprocess.run(_readonly_cmd(res, [f"results_dir={res}", "size=1024",
                                           "mask=Th-Hi-Re-Sh"]),
                       cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=240)
    assert r.returncode == 2, r.stderr
    assert "not writable" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert "NE " not in r.stdout                       # refused before solving


def test_memory_limit_refused_up_front_or_failed_row_stored(tmp_path):
    """S5: under ``ulimit -v`` a run that cannot fit is refused with the estimate and a
    hint; one that runs out of memory anyway is stored as failed (one line)."""
    limit = 3 * 2**30

    def lim():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    r = subprocess.run(CMD + ["size=4096", "weighted=true"], cwd=tmp_path, env=_env(),
                       capture_output=True, text=True, timeout=240, preexec_fn=lim)
    assert r.returncode == 2 and "GB (estimated)" in r.stderr and "size=" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1
    assert store.read_store(tmp_path / "results").empty
    r = subprocess.run(CMD + ["kind=noop", "args.alloc_mb=4000"], cwd=tmp_path, env=_env(),
                       capture_output=True, text=True, timeout=240, preexec_fn=lim)
    assert r.returncode == 2 and "MemoryError" in r.stderr, r.stderr
    _no_traceback(r.stderr)
    df = store.read_store(tmp_path / "results")
    assert len(df) == 1 and df.loc[0, "status"] == "failed"
    assert "MemoryError" in df.loc[0, "error"]


_POOL = """
from psbench.harness.grid import expand
from psbench.harness.shards import execute_runs
runs = expand({"name": "wk", "grids": [{"kind": "noop", "seed": list(range(8)),
                                        "args": {"sleep": 1.0}}]})
out = execute_runs(runs, root="res", sweep="wk", experiment="wk", jobs=2)
assert out["ok"] == 8, out
"""


def test_lost_pool_worker_restarts_the_pool(tmp_path):
    """A pool worker process itself killed (not a run process): the experiment restarts
    the pool for the runs not stored and completes."""
    proc = subprocess.Popen([sys.executable, "-c", _POOL], cwd=tmp_path, env=_env(),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0, busy = time.time(), []
    while time.time() - t0 < 120 and not busy:
        busy = [c for c in psutil.Process(proc.pid).children()
                if "loky" in " ".join(c.cmdline()) and c.children()]
        time.sleep(0.2)
    assert busy, "no worker ran a chunk"
    busy[0].kill()
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert "restarting the pool" in err
    df = store.read_store(tmp_path / "res")
    assert len(df) == 8 and set(df["status"]) == {"ok"}


def _stop_one_run(pid):
    """Freeze the run process of one busy pool worker of ``pid`` (SIGSTOP: its job
    cannot end any more) and return that worker, or None when none was caught mid-run."""
    for w in _busy_workers(pid):
        with contextlib.suppress(psutil.Error):
            for run in w.children():
                run.suspend()
                # the stop takes effect once the process is scheduled: wait for it
                t0 = time.time()
                while run.status() not in (psutil.STATUS_STOPPED, psutil.STATUS_ZOMBIE) \
                        and time.time() - t0 < 30:
                    time.sleep(0.01)
                if run.status() == psutil.STATUS_STOPPED:
                    return w
                run.resume()                   # was exiting: not mid-run
    return None


def test_sweep_survives_a_lost_worker(tmp_path):
    """Issue 23 item 2, reduced: a pool worker of a ``-m`` sweep SIGKILLed mid-sweep
    (its run frozen first, so the kill lands mid-run): every run stored, exit 0, no
    traceback, exactly one warning line, naming the lost job; runs stored before the
    loss are not computed again."""
    n = 6
    proc = subprocess.Popen(CMD + ["-m", "kind=noop", f"seed=range({n})", "args.sleep=1.5",
                                   "results_dir=res", "sweep=lost", "hydra.launcher.n_jobs=2"],
                            cwd=tmp_path, env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    runs = tmp_path / "res" / "runs" / "lost"
    try:
        _until(lambda: proc.poll() is not None or len(list(runs.glob("*.parquet"))) >= 1,
               "a first run stored")
        worker = _until(lambda: proc.poll() is not None or _stop_one_run(proc.pid),
                        "a worker caught mid-run")
        assert proc.poll() is None, proc.communicate()[1][-2000:]
        before = {f.name: f.stat().st_mtime_ns for f in runs.glob("*.parquet")}
        worker.kill()
        out, err = communicate(proc, timeout=300, what="the sweep with a lost worker")
    finally:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0, err[-2000:]
    _no_traceback(out, err)
    warn = [ln for ln in err.splitlines() if "warning" in ln]
    assert len(warn) == 1, err[-2000:]
    assert "worker process was lost" in warn[0] and "kind=noop seed=" in warn[0], warn[0]
    df = store.read_store(tmp_path / "res", sweep="lost")
    assert len(df) == n and df["run_id"].is_unique and set(df["status"]) == {"ok"}
    assert sorted(df["seed"]) == list(range(n))
    assert 0 < len(before) < n
    after = {f.name: f.stat().st_mtime_ns for f in runs.glob("*.parquet")}
    assert all(after[k] == v for k, v in before.items())      # stored: skipped, not redone


def test_outputs_written_by_the_run_process_before_its_row(tmp_path):
    """A single run's pictures are written by the supervised process that computed the
    run, before the row is stored: a stored "ok" row implies its outputs exist."""
    from psbench.harness.params import normalize, run_id
    from psbench.harness.supervise import run_supervised

    p = normalize({"surface": "spheres", "size": 24, "lights": "30x8"})
    row_file = store.run_path(tmp_path, "s", run_id(p))
    seen = {}

    def after(row, kept):
        (tmp_path / "marker").write_text(f"{os.getpid()} {row['status']} "
                                         f"{row_file.exists()} {sorted(kept)}")
        return "outputs written"

    row = run_supervised([p], root=tmp_path, sweep="s", after=after)[0]
    pid, status, existed, kept = (tmp_path / "marker").read_text().split(" ", 3)
    seen.update(pid=int(pid), status=status, existed=existed, kept=kept)
    assert seen["status"] == "ok" and seen["existed"] == "False"   # before the row
    assert "'result'" in seen["kept"] and "'scene'" in seen["kept"]
    assert row["_note"] == "outputs written" and row_file.is_file()
    if sys.platform.startswith("linux"):
        assert seen["pid"] != os.getpid()                           # in the run's process
    assert "_note" not in store.read_store(tmp_path).columns
