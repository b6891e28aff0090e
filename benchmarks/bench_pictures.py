"""Cost of the pictures a ``psbench`` run writes (``outputs=``), end to end and in process.

Run: ``python benchmarks/bench_pictures.py [--repeat 5] [--data PATH/TO/cat]``.

1. The command: ``psbench rerun=true`` (default scene, 512²) as a subprocess with
   ``outputs=none`` (the baseline: no pictures), ``outputs=pictures`` and ``outputs=all``
   (the default of a single run), interleaved, ``--repeat`` times each. Prints the median
   wall seconds and CPU seconds of the child (user + system) and the ratio to the baseline.
2. In process: :func:`psbench.io.write_outputs` for the default scene (and a DiLiGenT
   folder with ``--data``) at both levels, against the solve it illustrates (CPU medians).

The machine may be shared: figures are noisy; compare ratios and CPU, note the load.
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _child_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def command(repeat):
    exe = Path(sys.executable).parent / "psbench"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "psbench.harness.app"]
    levels = ("none", "pictures", "all")
    out = {k: ([], []) for k in levels}
    with tempfile.TemporaryDirectory() as tmp:
        env = {k: v for k, v in os.environ.items() if k != "PSBENCH_RESULTS"}
        for _ in range(repeat):
            for lvl in levels:
                c0, t0 = _child_cpu(), time.perf_counter()
                r = subprocess.run(cmd + ["rerun=true", f"outputs={lvl}"], cwd=tmp, env=env,
                                   capture_output=True, text=True)
                out[lvl][0].append(time.perf_counter() - t0)
                out[lvl][1].append(_child_cpu() - c0)
                if r.returncode:
                    raise SystemExit(r.stderr)
    base_w, base_c = (np.median(v) for v in out["none"])
    print("psbench rerun=true (default scene), median of", repeat)
    print(f"{'outputs':10s} {'wall s':>8s} {'ratio':>6s} {'CPU s':>8s} {'ratio':>6s}")
    for lvl in levels:
        w, c = (np.median(v) for v in out[lvl])
        print(f"{lvl:10s} {w:8.2f} {w / base_w:6.2f} {c:8.2f} {c / base_c:6.2f}")


def _cpu(f, repeat):
    ts = []
    for _ in range(repeat):
        c = time.process_time()
        f()
        ts.append(time.process_time() - c)
    return float(np.median(ts))


def in_process(repeat, data=None):
    import psbench as ps
    from psbench import io

    cases = []
    s = ps.make_surface("sombrero2", size=512)
    lay = ps.layout("45x8")
    sc = ps.render(s, lay, model="ts", noise=0.05, seed=0)
    cases.append(("sombrero2 512, 45x8", sc.images, lay, s.object_mask, s.normals))
    if data:
        ds = io.read_dataset(data)
        cases.append((f"{Path(data).name}, {ds.images.shape[0]} images", ds.images, ds.lights,
                      ds.object_mask, ds.normals))
    tmp = Path(tempfile.mkdtemp())
    print("\nin process, CPU seconds (median of", repeat, ")")
    print(f"{'case':28s} {'solve Th':>9s} {'pictures':>9s} {'all':>9s}")
    try:
        for name, images, lights, m, truth in cases:
            res = ps.solve(images, lights, mask="Th", object_mask=m)
            t_solve = _cpu(lambda: ps.solve(images, lights, mask="Th", object_mask=m), repeat)
            kw = dict(object_mask=m, images=images, truth_normals=truth, per_image=False)
            t_pic = _cpu(lambda: io.write_outputs(tmp / "p", res, arrays=False, ply=False,
                                                  obj=False, **kw), repeat)
            t_all = _cpu(lambda: io.write_outputs(tmp / "a", res, **kw), repeat)
            print(f"{name:28s} {t_solve:9.3f} {t_pic:9.3f} {t_all:9.3f}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--data", default=None, help="a DiLiGenT-layout folder (optional)")
    ap.add_argument("--skip-command", action="store_true")
    a = ap.parse_args()
    print("load average:", " ".join(f"{x:.2f}" for x in os.getloadavg()))
    if not a.skip_command:
        command(a.repeat)
    in_process(a.repeat, a.data)
