"""Harness end to end: the ``psbench`` command through subprocesses at tiny sizes.

Covers: one run prints a row and stores it; a -m sweep stores one row per run and a
re-run does no work; a configuration error refuses a sweep before any run; a SIGKILLed
parallel sweep resumes to exactly its rows; clean errors (exit 2) for unknown names;
nothing is written to the current directory; experiments through the command line.
"""
import os
import signal
import subprocess
import time

import pytest

from psbench.harness.store import read_store

from _cli import CMD, run_psbench
from _cli import clean_env as _env


def psbench(*args, cwd, timeout=120, **kw):
    return run_psbench(*args, cwd=cwd, timeout=timeout, **kw)


def _rows(root, sweep="adhoc"):
    return read_store(root, sweep=sweep)


def test_single_run_prints_row_and_keeps_cwd_clean(tmp_path):
    r = psbench("size=32", "surface=semisphere", "lights=30x8+60x8", "noise=0.1", "mask=None",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    line = next(ln for ln in r.stdout.splitlines() if "| stored " in ln)
    for part in ("semisphere", "30x8+60x8", "mask=None", "NE ", "mean angular error", "IE ",
                 "Lambert residual", "QF ", "(hi ", " s (render "):
        assert part in line, line
    assert "pictures (pictures" in r.stdout.splitlines()[-1]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results"]   # no outputs/, logs
    df = _rows(tmp_path / "results")
    assert len(df) == 1 and df.loc[0, "status"] == "ok" and df.loc[0, "n_images"] == 16
    assert df.loc[0, "ne_mean"] > 0 and df.loc[0, "t_solve"] >= 0
    # same command again: no work, says so
    r2 = psbench("size=32", "surface=semisphere", "lights=30x8+60x8", "noise=0.1", "mask=None",
                 cwd=tmp_path)
    assert r2.returncode == 0 and "skipped (stored)" in r2.stdout


def test_sweep_six_rows_rerun_no_work_config_error_refused(tmp_path):
    res = tmp_path / "res"
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    common = ["zenith=30,45,60", "size=32", f"results_dir={res}", "hydra/launcher=basic"]
    r = psbench("-m", "mask=None,Th", *common, cwd=cwd)
    assert r.returncode == 0, r.stderr
    name = "mask=None,Th_zenith=30,45,60"          # the store folder, named from the sweep
    df = _rows(res, name)
    assert len(df) == 6 and set(df["status"]) == {"ok"}
    assert sorted(df["lights"].unique()) == ["30x8", "45x8", "60x8"]
    mt = {p: p.stat().st_mtime_ns for p in (res / "runs" / name).iterdir()}
    # again, plus NL (needs 4 images): a configuration error refuses the whole sweep
    # before any run, and nothing is stored
    r2 = psbench("-m", "mask=None,Th,NL", *common, cwd=cwd)
    assert r2.returncode == 2 and "NL needs exactly 4 images" in r2.stderr
    assert "Traceback" not in r2.stderr and r2.stdout.count("stored") == 0
    assert sorted(p.name for p in (res / "runs").iterdir()) == [name]
    assert {p: p.stat().st_mtime_ns for p in (res / "runs" / name).iterdir()} == mt
    # the stored runs again: no work (a run failing while it runs is stored as failed and
    # the sweep goes on: tests/harness/test_run_faults.py)
    r3 = psbench("-m", "mask=None,Th", *common, cwd=cwd)
    assert r3.returncode == 0 and r3.stdout.count("skipped (stored)") == 6
    assert {p: p.stat().st_mtime_ns for p in mt} == mt
    assert list(cwd.iterdir()) == []


def test_sigkill_midway_then_resume_exactly_nine(tmp_path):
    res = tmp_path / "res"
    args = ["-m", "mask=Th,xNL,RA", "zenith=30,45,60", "size=48", f"results_dir={res}",
            "sweep=kill9"]
    proc = subprocess.Popen(CMD + args, cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, start_new_session=True)
    runs = res / "runs" / "kill9"
    t0 = time.time()
    try:
        while time.time() - t0 < 90 and proc.poll() is None:
            if runs.is_dir() and any(runs.glob("*.parquet")):
                break
            time.sleep(0.02)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
    finally:
        try:                                   # the sweep's joblib workers (same session)
            os.killpg(proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    at_kill = len(list(runs.glob("*.parquet")))
    r = psbench(*args, "hydra/launcher=basic", cwd=tmp_path)      # resume, in-process
    assert r.returncode == 0, r.stderr
    df = _rows(res, "kill9")
    assert len(df) == 9 and df["run_id"].is_unique and set(df["status"]) == {"ok"}
    assert len(list(runs.glob("*.parquet"))) == 9
    assert r.stdout.count("skipped (stored)") == at_kill
    print(f"rows stored when killed: {at_kill} of 9")


def test_clean_errors_exit_2(tmp_path):
    r = psbench("size=32", "mask=Bogus", cwd=tmp_path)
    assert r.returncode == 2
    assert "Bogus" in r.stderr and "Th" in r.stderr and "RA" in r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    r = psbench("size=32", "surface=blob", cwd=tmp_path)
    assert r.returncode == 2 and "semisphere" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "results" / "runs").exists()       # config errors store nothing
    r = psbench("colour=red", cwd=tmp_path)                    # unknown key: refused
    assert r.returncode == 2 and "unknown key 'colour'" in r.stderr
    r = psbench("+nosie=0.3", cwd=tmp_path)                    # a typo: refused, not ignored
    assert r.returncode == 2 and "did you mean 'noise'" in r.stderr
    r = psbench("size=32", "options.bogus=1", cwd=tmp_path)    # checked by the options class
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "'bogus'" in r.stderr and "max_iter" in r.stderr
    assert not (tmp_path / "results" / "runs").exists()
    r = psbench("--version", cwd=tmp_path)
    assert r.returncode == 0 and r.stdout.startswith("psbench ") and "Hydra" not in r.stdout


def test_sweep_over_method_options(tmp_path):
    args = ["-m", "size=32", "mask=Th-Hi", "options.max_iter=0,1", "hydra/launcher=basic"]
    r = psbench(*args, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    df = _rows(tmp_path / "results", sweep=None)   # a -m sweep has its own folder
    assert sorted(df["options"]) == ['{"max_iter": 0}', '{"max_iter": 1}']
    assert df["run_id"].is_unique


def test_experiment_command_and_height_file(tmp_path):
    import numpy as np

    # an experiment of another package: module + YAML, found through its entry point
    site = tmp_path / "site"
    (site / "tinypkg").mkdir(parents=True)
    (site / "tinypkg" / "__init__.py").write_text("")
    (site / "tinypkg" / "tiny.py").write_text(
        "TITLE = 'tiny'\n\ndef aggregate(rows):\n    return []\n")
    (site / "tinypkg" / "tiny.yaml").write_text(
        "experiment:\n  name: tiny\n  grids:\n"
        "    - {surface: [semisphere, bump.npy], mask: [None, Th], noise: [0.0, 0.1]}\n"
        "  fixed: {lights: 45x8}\n"
        "  scales:\n    full: {size: 512}\n    ci: {size: 24, seed: [0]}\n")
    (site / "tinypkg-0.1.dist-info").mkdir()
    (site / "tinypkg-0.1.dist-info" / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: tinypkg\nVersion: 0.1\n")
    (site / "tinypkg-0.1.dist-info" / "entry_points.txt").write_text(
        "[psbench.experiments]\ntiny = tinypkg.tiny\n")
    yy, xx = np.mgrid[:24, :24]
    np.save(tmp_path / "bump.npy", 6.0 * np.exp(-((xx - 12) ** 2 + (yy - 12) ** 2) / 40.0))
    args = ["+experiment=tiny", "scale=ci", "jobs=1"]
    env = dict(_env(), PYTHONPATH=os.pathsep.join(
        p for p in (str(site), os.environ.get("PYTHONPATH")) if p))
    r = subprocess.run(CMD + args, cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    df = read_store(tmp_path / "results", experiment="tiny")
    assert len(df) == 8 and set(df["status"]) == {"ok"}
    assert set(df["size"]) == {24} and (df["surface"].str.endswith("bump.npy")).sum() == 4
    assert "8 of 8" in r.stderr
    r = subprocess.run(CMD + args, cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and "8 of 8 runs skipped (stored)" in r.stderr


@pytest.mark.realdata
def test_data_folder_run(tmp_path, diligent):
    d = diligent / "cat"
    r = psbench(f"data={d}", "mask=None", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    df = _rows(tmp_path / "results")
    assert df.loc[0, "n_images"] == 96 and pd_isna(df.loc[0, "lights"])
    assert 8.0 < df.loc[0, "ne_mean"] < 8.8 and df.loc[0, "ie_l2"] > 0   # published 8.41


def pd_isna(v):
    import pandas as pd

    return pd.isna(v)


def test_a_command_that_hangs_fails_with_its_stacks(tmp_path):
    """SIGUSR2 makes every psbench process print its threads' stacks and go on; the
    tests' runner uses it on a timeout, so a hang says where it hung."""
    with pytest.raises(pytest.fail.Exception) as info:
        psbench("kind=noop", "args.sleep=30", f"results_dir={tmp_path / 'res'}", "sweep=hang",
                cwd=tmp_path, timeout=6)
    text = str(info.value)
    assert "did not finish in 6 s" in text
    assert "most recent call first" in text and "supervise.py" in text, text[-3000:]
    assert "in noop" in text, text[-3000:]             # the run process, in its sleep
