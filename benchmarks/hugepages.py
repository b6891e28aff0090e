"""What numpy's huge-page advice costs a solve: psbench's default (advice off while it
solves, :mod:`psbench._shared.memory`) against numpy's (``NUMPY_MADVISE_HUGEPAGE=1``).
The module's other policy (glibc keeping freed memory) holds in both.

Each repeat is a fresh process per setting (alternating, so both see the same load):
it loads a DiLiGenT object, compiles on a 24 x 24 crop, then solves the whole object
``--solves`` times and reports, per solve, the wall time, the user and system CPU time
and the minor page faults (``getrusage``). One numba thread. Prints the medians over
the repeats per solve index, the ratio default / numpy's advice, the host's
transparent-huge-page settings and the load average.

Usage::

    python benchmarks/hugepages.py [--data DIR] [--objects cat] [--methods robust tsfit]
                                   [--repeat 3] [--solves 3]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

CHILD = r"""
import json, resource, sys, time
import psbench as ps
obj, method, data, n = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
d = ps.io.read_dataset(f"{data}/{obj}")
ps.solve(d.images[:, :24, :24], d.lights, method=method)  # compile / load the kernels
rows = []
for _ in range(n):
    r0, t0 = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
    ps.solve(d.images, d.lights, method=method, object_mask=d.object_mask)
    wall, r1 = time.perf_counter() - t0, resource.getrusage(resource.RUSAGE_SELF)
    rows.append(dict(wall=wall, user=r1.ru_utime - r0.ru_utime, sys=r1.ru_stime - r0.ru_stime,
                     faults=r1.ru_minflt - r0.ru_minflt))
print(json.dumps(rows))
"""


def run(obj, method, data, solves, advice):
    env = dict(os.environ, NUMBA_NUM_THREADS="1", OMP_NUM_THREADS="1")
    env.pop("NUMPY_MADVISE_HUGEPAGE", None)
    if advice:
        env["NUMPY_MADVISE_HUGEPAGE"] = "1"
    out = subprocess.run([sys.executable, "-W", "ignore", "-c", CHILD, obj, method, data,
                          str(solves)], env=env, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _thp():
    base = Path("/sys/kernel/mm/transparent_hugepage")
    return {f: (base / f).read_text().strip() if (base / f).exists() else "n/a"
            for f in ("enabled", "defrag")}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1]
                                          / "../shared/data/diligent"))
    ap.add_argument("--objects", nargs="+", default=["cat"])
    ap.add_argument("--methods", nargs="+", default=["robust", "tsfit"])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--solves", type=int, default=3)
    a = ap.parse_args(argv)
    print(f"transparent huge pages: {_thp()}; load average at start: {os.getloadavg()}")
    print("| object | method | solve | wall s (advice / default) | ratio | user s | sys s | "
          "page faults |")
    print("|---|---|---|---|---|---|---|---|")
    for obj in a.objects:
        for m in a.methods:
            res = {True: [], False: []}
            for _ in range(a.repeat):
                for advice in (True, False):
                    res[advice].append(run(obj, m, a.data, a.solves, advice))
            for j in range(a.solves):
                med = {adv: {key: float(np.median([rows[j][key] for rows in v]))
                             for key in ("wall", "user", "sys", "faults")}
                       for adv, v in res.items()}
                on, off = med[True], med[False]
                print(f"| {obj} | {m} | {j + 1} | {on['wall']:.2f} / {off['wall']:.2f} | "
                      f"{off['wall'] / on['wall']:.3f} | {on['user']:.2f} / {off['user']:.2f} | "
                      f"{on['sys']:.2f} / {off['sys']:.2f} | {on['faults']:.0f} / "
                      f"{off['faults']:.0f} |", flush=True)
    print(f"load average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
