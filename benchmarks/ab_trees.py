"""A/B timing of two psbench source trees in one session: a render, the solves that end in
the per-pixel 3x3 solve (the masked solve, WPS and its oracle, robust methods on the
compiled and the numpy path, the default robust and tsfit, the held-out validation) and
a small experiment (table2_1 at CI scale), each tree in fresh processes, taken in turn.

    python benchmarks/ab_trees.py BEFORE_TREE [AFTER_TREE] [--runs 5] [--size 256]
                                  [--no-experiment]

Each child imports psbench from its tree (``python -c`` with the tree as working
directory), warms up (numba cache, imports) and prints the medians of ``--runs`` timed
calls; the experiment is timed as a whole process (``psbench +experiment=table2_1
scale=ci`` into a throwaway store). Ratios are after / before per round (rounds
alternate B A B A ...), reported as their median; the load average is printed beside.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHILD = r"""
import json, sys, time, warnings
warnings.simplefilter("ignore")
import numpy as np, psbench as ps
size, runs = int(sys.argv[1]), int(sys.argv[2])
surf = ps.make_surface("sombrero2", size=size)
lay = ps.layout("30x8+60x8")
def timed(f):
    f()
    out = []
    for _ in range(runs):
        t = time.perf_counter(); f(); out.append(time.perf_counter() - t)
    return float(np.median(out))
scene = ps.render(surf, lay, model="ts", noise=0.05, seed=0)
r = timed(lambda: ps.render(surf, lay, model="ts", noise=0.05, seed=0))
s = timed(lambda: ps.solve(scene.images, lay, mask="Th-Hi-Re-Sh", object_mask=surf.object_mask))
w = timed(lambda: ps.solve(scene.images, lay, method="wps", object_mask=surf.object_mask))
wo = timed(lambda: ps.solve(scene.images, lay, method="wps", weight="oracle",
                            truth_normals=surf.normals, object_mask=surf.object_mask))
rob = {m: timed(lambda m=m: ps.solve(scene.images, lay, method=m, object_mask=surf.object_mask))
       for m in ("trim", "huber", "sbl", "robust", "tsfit")}
res = ps.solve(scene.images, lay, mask="Th-Hi-Re-Sh", object_mask=surf.object_mask)
try:                     # a tree from before the validation error has none
    from psbench.solve.validation import validate
except ImportError:
    v = float("nan")
else:
    v = timed(lambda: validate(scene.images, lay, res.valid, object_mask=surf.object_mask))
ne = ps.normal_error(res.normals, surf.normals, object_mask=surf.object_mask)
print(json.dumps(dict(render=r, solve=s, wps=w, wps_oracle=wo, validate=v, **rob, ne=float(ne),
                      file=ps.__file__)))
"""
EXPERIMENT = ("import sys; from psbench.harness.app import main; "
              "sys.argv = ['psbench', '+experiment=table2_1', 'scale=ci', 'jobs=1']; main()")


def child(tree, size, runs):
    out = subprocess.run([sys.executable, "-c", CHILD, str(size), str(runs)], cwd=tree,
                         capture_output=True, text=True, check=True)
    row = json.loads(out.stdout.strip().splitlines()[-1])
    assert row["file"].startswith(str(tree)), row["file"]
    return row


def experiment(tree):
    with tempfile.TemporaryDirectory() as store:
        env = dict(os.environ, PSBENCH_RESULTS=store)
        t = time.perf_counter()
        subprocess.run([sys.executable, "-c", EXPERIMENT], cwd=tree, env=env,
                       capture_output=True, text=True, check=True)
        return time.perf_counter() - t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("before")
    ap.add_argument("after", nargs="?", default=str(Path(__file__).resolve().parents[1]))
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--no-experiment", action="store_true", help="skip the experiment timing")
    a = ap.parse_args(argv)
    trees = {"before": Path(a.before).resolve(), "after": Path(a.after).resolve()}
    for tree in trees.values():  # warm-up: numba caches, imports
        child(tree, 32, 1)
        if not a.no_experiment:
            experiment(tree)
    rows = {k: [] for k in trees}
    load0 = os.getloadavg()[0]
    for _ in range(a.rounds):
        for k in ("before", "after"):
            row = child(trees[k], a.size, a.runs)
            row["experiment"] = float("nan") if a.no_experiment else experiment(trees[k])
            rows[k].append(row)
    print(f"sombrero2 {a.size}^2, 30x8+60x8, TS, 5 % noise; medians of {a.runs} calls per "
          f"process, {a.rounds} rounds; load average {load0:.1f} before, "
          f"{os.getloadavg()[0]:.1f} after")
    print("| what | before s | after s | after / before (median of rounds) |")
    print("|---|---|---|---|")
    whats = ["render", "solve", "wps", "wps_oracle", "trim", "huber", "sbl", "robust", "tsfit",
             "validate"]
    for what in whats + ([] if a.no_experiment else ["experiment"]):
        b = [r[what] for r in rows["before"]]
        f = [r[what] for r in rows["after"]]
        ratio = statistics.median(x / y for x, y in zip(f, b)) if b[0] == b[0] else float("nan")
        print(f"| {what} | {statistics.median(b):.4f} | {statistics.median(f):.4f} | "
              f"{ratio:.3f} |")
    ne = {k: rows[k][0]["ne"] for k in rows}
    print(f"NE of the Th-Hi-Re-Sh solve: before {ne['before']:.6f}, after {ne['after']:.6f} deg")


if __name__ == "__main__":
    main()
