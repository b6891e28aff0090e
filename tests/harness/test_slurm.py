"""psbench on a real SLURM cluster: a throwaway single node (``benchmarks/slurm_local.sh``).

Marked ``slurm`` and deselected by default; as root: ``python -m pytest -m slurm
tests/harness/test_slurm.py`` (``.ci/run`` does). SLURM is installed with apt-get when
missing; munged, slurmctld and slurmd run from a temporary folder and exactly those
daemons are stopped afterwards, also when a test fails. Covers: a ``-m`` sweep through
``hydra/launcher=submitit_slurm`` (one array job), a ci-scale experiment through
``launcher=submitit_slurm shards=2`` (exactly its grid, no duplicates, all ok; a second
call has nothing to do) and a shard job cancelled before it ran (reported, exit 1, not
waited for forever: the cluster has no accounting database, so ``sacct`` fails).
How psbench reads ``squeue`` is also checked without a cluster (a stand-in ``squeue``),
in the default run.
"""
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from psbench.harness import grid
from psbench.harness import spec as S
from psbench.harness.params import normalize, run_id
from psbench.harness.shards import _slurm_ended

SCRIPT = Path(__file__).resolve().parents[2] / "benchmarks" / "slurm_local.sh"
_BIN = Path(sys.executable).parent / "psbench"
CMD = [str(_BIN)] if _BIN.exists() else [sys.executable, "-m", "psbench.harness.app"]
_SBIN = os.pathsep.join([os.environ.get("PATH", ""), "/usr/sbin", "/sbin"])


def _why_not():
    """Why this machine cannot host the throwaway cluster (None: it can)."""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return "the SLURM test needs root (slurmd starts jobs as their user)"
    have = all(shutil.which(c, path=_SBIN) for c in ("munged", "slurmctld", "slurmd", "sbatch"))
    if not have and not shutil.which("apt-get"):
        return "SLURM is not installed and apt-get is not available to install it"
    return None


def _alive(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"     # a zombie has ended
    except OSError:
        return False


@pytest.mark.parametrize("out, rc, want", [
    ("11 RUNNING\n12 CANCELLED\n13 PENDING\n", 0, {"12": "CANCELLED", "14": "GONE"}),
    ("11 COMPLETED\n12 TIMEOUT\n13 COMPLETING\n14 OUT_OF_MEMORY\n", 0,
     {"11": "COMPLETED", "12": "TIMEOUT", "14": "OUT_OF_MEMORY"}),
    ("slurm_load_jobs error: Invalid job id specified", 1,
     dict.fromkeys(["11", "12", "13", "14"], "GONE")),
    ("squeue: error: Unable to contact slurm controller", 1, None),
])
def test_squeue_states_read(tmp_path, monkeypatch, out, rc, want):
    fake = tmp_path / "squeue"
    stream = ">&2" if rc else ""
    fake.write_text(f"#!/bin/sh\nprintf '%s' '{out}' {stream}\nexit {rc}\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path))
    assert _slurm_ended(["11", "12", "13", "14"]) == want


def test_squeue_missing_tells_nothing(tmp_path, monkeypatch):
    monkeypatch.setenv("PATH", str(tmp_path))
    assert _slurm_ended(["11"]) is None


@pytest.fixture(scope="module")
def cluster(request, tmp_path_factory):
    why = _why_not()
    if why:
        pytest.skip(why)
    base = tmp_path_factory.mktemp("slurm")
    folder = base / "cluster"
    env = dict(os.environ, PSBENCH_SLURM_DIR=str(folder))
    env.pop("SLURM_CONF", None)

    def stop():                  # registered before start: a half-started cluster is stopped
        pids, munge = [], None
        if (folder / "pids").is_file():
            pids = [int(ln.split()[1]) for ln in (folder / "pids").read_text().splitlines()]
        if (folder / "munge_dir").is_file():
            munge = Path((folder / "munge_dir").read_text().strip())
        r = subprocess.run(["bash", str(SCRIPT), "stop"], env=env, capture_output=True,
                           text=True, timeout=120)
        assert r.returncode == 0, r.stderr
        assert not [p for p in pids if _alive(p)], f"daemons still running: {pids}"
        assert not folder.exists() and not (munge and munge.exists())

    request.addfinalizer(stop)
    t0 = time.monotonic()
    r = subprocess.run(["bash", str(SCRIPT), "start"], env=env, capture_output=True, text=True,
                       timeout=900)
    assert r.returncode == 0, r.stderr
    assert len((folder / "pids").read_text().splitlines()) == 3       # munged, ctld, slurmd
    conf = r.stdout.strip().splitlines()[-1].split("=", 1)[1]
    print(f"\ncluster started in {time.monotonic() - t0:.1f} s (includes any installation)")
    run_env = dict(os.environ, SLURM_CONF=conf, PATH=_SBIN)
    for k in ("PSBENCH_RESULTS", "HYDRA_FULL_ERROR"):
        run_env.pop(k, None)
    return dict(folder=folder, env=run_env)


def psbench(cluster, *args, cwd, timeout=600):
    return subprocess.run(CMD + list(args), cwd=cwd, env=cluster["env"], capture_output=True,
                          text=True, timeout=timeout)


def _raw_rows(res, sweep):
    """Every stored row, file by file (no de-duplication), as dicts."""
    files = sorted((res / "runs" / sweep).glob("*.parquet"))
    return [row for p in files for row in pq.read_table(p).to_pylist()]


def _completed(cluster):
    """Job ids the controller recorded as completed (jobcomp/filetxt)."""
    log = cluster["folder"] / "log" / "jobcomp.txt"
    text = log.read_text() if log.is_file() else ""
    return re.findall(r"JobId=(\d+) .*?JobState=COMPLETED", text)


@pytest.mark.slurm
def test_sweep_runs_as_one_array_job(cluster, tmp_path):
    res = tmp_path / "results"
    before = len(_completed(cluster))
    r = psbench(cluster, "-m", "hydra/launcher=submitit_slurm", "mask=None,Th",
                "lights=30x8,60x8", "size=32", f"results_dir={res}", "sweep=slurm_sweep",
                cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    rows = _raw_rows(res, "slurm_sweep")
    want = {run_id(normalize({**S.defaults(), "mask": m, "lights": lt, "size": 32}))
            for m in ("None", "Th") for lt in ("30x8", "60x8")}
    assert len(rows) == 4 and {x["run_id"] for x in rows} == want
    assert {x["status"] for x in rows} == {"ok"}
    # the four runs were the tasks of one SLURM array job, each with its result
    sub = res / "hydra" / "multirun" / ".submitit"
    tasks = sorted(p.name for p in sub.iterdir() if p.is_dir() and "_" in p.name)
    assert len(tasks) == 4 and len({t.split("_")[0] for t in tasks}) == 1, tasks
    for t in tasks:
        assert (sub / t / f"{t}_0_result.pkl").is_file()
    assert len(_completed(cluster)) == before + 4


@pytest.mark.slurm
def test_experiment_in_two_shard_jobs(cluster, tmp_path):
    res = tmp_path / "results"
    args = ["+experiment=table5_4", "scale=ci", "launcher=submitit_slurm", "shards=2",
            f"results_dir={res}"]
    r = psbench(cluster, *args, cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    m = re.search(r"submitted 2 shard job\(s\) with submitit_slurm \((\d+), (\d+)\)", r.stderr)
    assert m, r.stderr
    assert set(m.groups()) <= set(_completed(cluster))
    rows = _raw_rows(res, "table5_4")
    want = {run_id(p) for p in grid.expand("table5_4", "ci")}
    ids = [x["run_id"] for x in rows]
    assert len(want) == 57 and len(ids) == len(set(ids)) == 57 and set(ids) == want
    assert {x["status"] for x in rows} == {"ok"}
    assert all(x["ne_mean"] > 0 for x in rows)
    # again: every run is stored, no job is submitted
    r2 = psbench(cluster, *args, cwd=tmp_path)
    assert r2.returncode == 0, r2.stderr
    assert "57 of 57 runs skipped (stored)" in r2.stderr and "submitted" not in r2.stderr
    assert len(_raw_rows(res, "table5_4")) == 57


@pytest.mark.slurm
def test_cancelled_shard_job_is_reported(cluster, tmp_path):
    """A shard job that ends without a result (here: cancelled while held) is reported
    and counted as failed; psbench does not wait for it forever."""
    res = tmp_path / "results"
    cmd = CMD + ["+experiment=table2_1", "scale=ci", "launcher=submitit_slurm", "shards=1",
                 "submitit.slurm_additional_parameters={hold: true}", f"results_dir={res}"]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=cluster["env"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        held = []
        t0 = time.monotonic()
        while not held and time.monotonic() - t0 < 120 and proc.poll() is None:
            q = subprocess.run(["squeue", "-h", "-o", "%i %r"], env=cluster["env"],
                               capture_output=True, text=True)
            held = [ln.split()[0] for ln in q.stdout.splitlines() if "Held" in ln]
            time.sleep(0.5)
        assert len(held) == 1, "no held shard job appeared"
        subprocess.run(["scancel", held[0]], env=cluster["env"], check=True)
        out, err = proc.communicate(timeout=180)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 1, out + err
    assert f"shard job {held[0]} failed" in err and "ended (CANCELLED) without a result" in err
    assert _raw_rows(res, "table2_1") == []
