"""A/B timing of ``robust`` and ``tsfit`` (validation error, held-out fallback) against a tree before.

Runs each tree in its own process (``PYTHONPATH`` = the tree), alternating the trees
per repeat so that both see the same load: DiLiGenT cat and bear with all 96 lights,
``robust`` and ``tsfit`` with their defaults, one numba thread. Reports the median wall
and CPU time of the solve over ``--repeat`` runs (after a warm-up solve that compiles
the kernels), the ratio new / before (of the medians), the NE of both trees, the new tree's fallback
fraction and the load average.

Usage::

    python benchmarks/validation_ab.py --before /tmp/ve-before [--repeat 3] [--data DIR]

The children inherit the environment: ``NUMPY_MADVISE_HUGEPAGE=0`` (or ``=1``) gives
both trees the same page mapping, which isolates the compute from the huge-page stalls
that psbench's solve avoids by default (:mod:`psbench._shared.memory`).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

CHILD = r"""
import json, sys, time, numpy as np
import psbench as ps
obj, method, data = sys.argv[1], sys.argv[2], sys.argv[3]
d = ps.io.read_dataset(f"{data}/{obj}")
om = d.object_mask
ps.solve(d.images[:, :24, :24], d.lights, method=method)  # compile
t0, c0 = time.perf_counter(), time.process_time()
r = ps.solve(d.images, d.lights, method=method, object_mask=om)
wall, cpu = time.perf_counter() - t0, time.process_time() - c0
ne = float(ps.normal_error(r.normals, d.normals, object_mask=om))
ve = getattr(r, "ve", None)
fb = getattr(r, "fallback", None)
print(json.dumps(dict(wall=wall, cpu=cpu, ne=ne, ve=None if ve is None else ve.mean,
                      fb=None if fb is None else float(fb[om].mean()), file=ps.__file__)))
"""


def run(tree, obj, method, data):
    env = dict(os.environ, PYTHONPATH=str(tree), NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    # run from the tree (an editable install's import hook would win over PYTHONPATH)
    out = subprocess.run([sys.executable, "-c", CHILD, obj, method, data], env=env,
                         cwd=str(tree), capture_output=True, text=True, check=True)
    row = json.loads(out.stdout.strip().splitlines()[-1])
    assert row["file"].startswith(str(Path(tree).resolve())), row["file"]   # the right tree
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True, help="worktree of the tree before")
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / "../shared/data/diligent"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--objects", nargs="+", default=["cat", "bear"])
    ap.add_argument("--methods", nargs="+", default=["robust", "tsfit"])
    a = ap.parse_args(argv)
    new = Path(__file__).resolve().parents[1]
    import numpy as np
    print(f"load average at start: {os.getloadavg()}")
    print("| object | method | before wall s | new wall s | ratio | before cpu s | new cpu s | "
          "NE before | NE new | ve mean new | fallback new |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for obj in a.objects:
        for m in a.methods:
            res = {"before": [], "new": []}
            for _ in range(a.repeat):
                res["before"].append(run(a.before, obj, m, a.data))
                res["new"].append(run(new, obj, m, a.data))
            med = {t: {k: float(np.median([r[k] for r in v])) for k in ("wall", "cpu", "ne")}
                   for t, v in res.items()}
            b, n = med["before"], med["new"]
            print(f"| {obj} | {m} | {b['wall']:.2f} | {n['wall']:.2f} | {n['wall'] / b['wall']:.3f} "
                  f"| {b['cpu']:.2f} | {n['cpu']:.2f} | {b['ne']:.2f} | {n['ne']:.2f} | "
                  f"{res['new'][-1]['ve']:.4f} | {res['new'][-1]['fb']} |", flush=True)
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
