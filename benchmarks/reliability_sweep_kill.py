"""A pool worker of an N-run ``psbench -m`` sweep SIGKILLed midway: the sweep must
complete (N/N stored, exit 0) with one warning line naming the lost job.

Usage: python benchmarks/reliability_sweep_kill.py [N] (default 50; kind=noop runs
sleeping 0.3 s, two workers). ``noop`` is the tests' self-test kind, a plug-in found
through ``tests/plugins`` (put on ``PYTHONPATH`` here).
"""
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

from psbench.harness import store

PLUGINS = Path(__file__).resolve().parents[1] / "tests" / "plugins"


def main(n=50):
    exe = Path(sys.executable).parent / "psbench"
    with tempfile.TemporaryDirectory() as d:
        env = {k: v for k, v in os.environ.items() if k != "PSBENCH_RESULTS"}
        env["PYTHONPATH"] = os.pathsep.join([str(PLUGINS)] + [
            p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
        proc = subprocess.Popen([str(exe), "-m", "kind=noop", f"seed=range({n})",
                                 "args.sleep=0.3", "results_dir=res", "sweep=kill",
                                 "hydra.launcher.n_jobs=2"], cwd=d, env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        killed = None
        t0 = time.time()
        while time.time() - t0 < 600 and killed is None:
            time.sleep(0.2)
            n_stored = len(list((Path(d) / "res" / "runs" / "kill").glob("*.parquet")))
            if n_stored < n // 3:
                continue
            busy = [c for c in psutil.Process(proc.pid).children()
                    if "loky" in " ".join(c.cmdline()) and c.children()]
            if busy:
                busy[0].kill()
                killed = n_stored
        out, err = proc.communicate(timeout=900)
        df = store.read_store(Path(d) / "res", sweep="kill")
        warn = [ln for ln in err.splitlines() if "warning" in ln]
        print(f"killed a worker after {killed} stored runs; exit {proc.returncode}; "
              f"{int((df['status'] == 'ok').sum())}/{n} stored ok; {len(warn)} warning line(s); "
              f"traceback: {'Traceback' in err}")
        for ln in warn:
            print("  " + ln)
        return 0 if proc.returncode == 0 and (df["status"] == "ok").sum() == n and len(warn) == 1 \
            else 1


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 50))
