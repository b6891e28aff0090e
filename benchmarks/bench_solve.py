"""Speed of psbench.solve against the thesis's Matlab times (Table 5.3).

Usage::

    python benchmarks/bench_solve.py [--size 512] [--runs 5] [--big 2048] [--surface sombrero]
    python benchmarks/bench_solve.py --against OTHER_TREE [--rounds 5] [--size 512]

Scenes: Torrance-Sparrow images with shadows, no noise, 16 lights ("30x8+60x8") or
4 lights ("45x4") for CJ. Prints the median wall time of ``--runs`` runs (timed
inside ``solve``: ``Result.timings["total"]``), the ratio to None of the same run, the
psbench target and the thesis's Matlab time (Table 5.3: averages over its test set,
Intel Core 2 Quad, images of 512 x 512; a context figure, not a like-for-like
comparison). ``--big`` runs weighted Th-Hi-Re-Sh once at that size in a subprocess
and reports its time and peak RSS (``resource.getrusage(RUSAGE_CHILDREN)``).

``--against OTHER_TREE`` compares two source trees (e.g. a ``git worktree`` of an older
commit) in one session: each round runs this script once per tree in a subprocess
(``PYTHONPATH`` = the tree, alternating which goes first), and prints, per case, the
median over rounds of each tree's median with the ratio this tree / other.

The machine is shared: figures are noisy, compare ratios rather than absolutes; the
process CPU time column is the steadier figure. ``--blas-threads`` (default 1) sets
OPENBLAS_NUM_THREADS/OMP_NUM_THREADS before numpy loads: on a machine shared by many
busy processes multi-threaded OpenBLAS makes the small (k x 3) products of PS up to
100x slower in median wall time (threads spin waiting for cores), single-threaded it
does not.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time


def _blas_threads(argv):
    n = "1"
    for i, a in enumerate(argv):
        if a == "--blas-threads" and i + 1 < len(argv):
            n = argv[i + 1]
        elif a.startswith("--blas-threads="):
            n = a.split("=", 1)[1]
    if n != "0":  # 0: leave the library defaults
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ[var] = n
    return n


BLAS_THREADS = _blas_threads(sys.argv) if __name__ == "__main__" else None

import numpy as np  # noqa: E402

import psbench as ps  # noqa: E402
from psbench.solve import solve  # noqa: E402

# mask, lights, target seconds, Matlab seconds (Table 5.3)
CASES = [
    ("None", "30x8+60x8", 0.010, 0.11),
    ("Th", "30x8+60x8", 0.080, 1.67),
    ("Th-Hi-Re-Sh", "30x8+60x8", 1.0, 20.12),
    ("xNL", "30x8+60x8", 0.5, 16.94),
    ("RA", "30x8+60x8", 0.5, 5.00),
    ("None", "45x4", None, 0.08),
    ("CJ", "45x4", 0.050, 0.48),
]

CHILD = r"""
import json, sys, time, resource
import numpy as np
import psbench as ps
from psbench.solve import solve
images = np.load(sys.argv[1])
mask = np.load(sys.argv[2])
lay = ps.layout(sys.argv[3])
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
c0 = time.process_time()
t0 = time.perf_counter()
res = solve(images, lay, mask="Th-Hi-Re-Sh", weighted=True, object_mask=mask)
t = time.perf_counter() - t0
print(json.dumps({"seconds": t, "cpu": time.process_time() - c0, "timings": res.timings,
                  "iterations": res.iterations, "changed": res.info.get("changed"),
                  "rss_before_solve_mb": base / 1024.0}))
"""


def _scene(surface, size, lights):
    surf = ps.make_surface(surface, size=size)
    lay = ps.layout(lights)
    return surf, lay, ps.render(surf, lay, model="ts", shadows=True)


def _object_mask(surf):
    """The object region; older trees (before the object_mask name) call it ``mask``."""
    om = getattr(surf, "object_mask", None)
    return surf.mask if om is None else om


def _ne(res, surf, om):
    try:
        return ps.normal_error(res.normals, surf.normals, object_mask=om)
    except TypeError:                      # an older tree: positional region
        return ps.normal_error(res.normals, surf.normals, om)


def bench(size=512, runs=5, surface="sombrero"):
    scenes = {}
    rows = []
    base = {}
    for mask, lights, target, matlab in CASES:
        if lights not in scenes:
            scenes[lights] = _scene(surface, size, lights)
        surf, lay, sc = scenes[lights]
        om = _object_mask(surf)
        solve(sc.images, lay, mask=mask, object_mask=om)  # warm-up (imports, caches)
        ts, cpu = [], []
        for _ in range(runs):
            c0 = time.process_time()
            res = solve(sc.images, lay, mask=mask, object_mask=om)
            cpu.append(time.process_time() - c0)
            ts.append(res.timings["total"])
        med = float(np.median(ts))
        if mask == "None":
            base[lights] = med
        ne = _ne(res, surf, om)
        rows.append((mask, lights, med, med / base[lights], target, matlab, ne, res.iterations,
                     float(np.min(ts)), float(np.median(cpu))))
    print(f"\npsbench.solve at {size}x{size}, surface {surface}, TS with shadows, "
          f"median of {runs} runs (ms)")
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'default')}")
    print(f"{'mask':14s} {'lights':10s} {'median':>9s} {'min':>8s} {'cpu':>8s} {'xNone':>6s} "
          f"{'target':>7s} {'ok':>3s} {'Matlab':>7s} {'speedup':>8s} {'NE deg':>7s} {'iter':>4s}")
    for mask, lights, med, ratio, target, matlab, ne, it, mn, cpu in rows:
        tg = f"{target * 1e3:7.0f}" if target else f"{'-':>7s}"
        ok = ("yes" if med <= target else "NO") if target else "-"
        print(f"{mask:14s} {lights:10s} {med * 1e3:9.1f} {mn * 1e3:8.1f} {cpu * 1e3:8.1f} "
              f"{ratio:6.1f} {tg} {ok:>3s} {matlab * 1e3:7.0f} {matlab / med:8.0f} {ne:7.2f} {it:4d}")
    print("median/min: wall ms timed inside solve; cpu: process CPU ms (all threads); "
          "ok compares the median with the target; Matlab: Table 5.3 (s x 1000)")
    return rows


def bench_big(size=2048, surface="sombrero", lights="30x8+60x8"):
    surf, lay, sc = _scene(surface, size, lights)
    with tempfile.TemporaryDirectory() as d:
        fi, fm = os.path.join(d, "images.npy"), os.path.join(d, "mask.npy")
        np.save(fi, sc.images)
        np.save(fm, surf.object_mask)
        del sc
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", CHILD, fi, fm, lights], check=True,
                             capture_output=True, text=True)
        wall = time.perf_counter() - t0
    info = json.loads(out.stdout.strip().splitlines()[-1])
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0  # kB -> MB (Linux)
    print(f"\nweighted Th-Hi-Re-Sh at {size}x{size}, {lights}: solve {info['seconds']:.2f} s wall, "
          f"{info['cpu']:.2f} s CPU (target <= 15 s: {'yes' if info['seconds'] <= 15 else 'NO'}), "
          f"load average {os.getloadavg()[0]:.1f}, rounds {info['iterations']} "
          f"(changed {info['changed']}), peak RSS {peak:.0f} MB "
          f"(target <= 4096 MB: {'yes' if peak <= 4096 else 'NO'}; "
          f"images + interpreter before solve {info['rss_before_solve_mb']:.0f} MB), "
          f"subprocess wall {wall:.1f} s")
    print("  stages (s): " + ", ".join(f"{k} {v:.2f}" for k, v in info["timings"].items()))
    return info, peak


def against(other, size=512, runs=5, rounds=5, surface="sombrero", blas="1"):
    """Interleaved A/B of this tree against ``other`` (module docs)."""
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    trees = {"this": here, "other": os.path.abspath(other)}
    got = {"this": [], "other": []}
    load0 = os.getloadavg()
    with tempfile.TemporaryDirectory() as d:
        for r in range(rounds):
            for name in (("other", "this") if r % 2 == 0 else ("this", "other")):
                out = os.path.join(d, f"{name}{r}.json")
                env = dict(os.environ, PYTHONPATH=trees[name])
                subprocess.run([sys.executable, os.path.abspath(__file__), "--size", str(size),
                                "--runs", str(runs), "--big", "0", "--surface", surface,
                                "--blas-threads", blas, "--json", out], check=True, env=env,
                               stdout=subprocess.DEVNULL)
                with open(out) as fh:
                    got[name].append(json.load(fh))
    load1 = os.getloadavg()
    print(f"\nA/B at {size}x{size}, surface {surface}: {rounds} interleaved rounds x {runs} runs "
          f"per tree; medians over rounds of each round's median (ms)")
    print(f"this  = {trees['this']}\nother = {trees['other']}")
    print(f"load average {load0[0]:.1f} at start, {load1[0]:.1f} at end, {os.cpu_count()} cores")
    print(f"{'mask':14s} {'lights':10s} {'other':>8s} {'this':>8s} {'ratio':>6s} "
          f"{'min oth':>8s} {'min this':>8s} {'ratio':>6s} {'cpu oth':>8s} {'cpu this':>8s} "
          f"{'ratio':>6s}")
    table = []
    for i, row in enumerate(got["this"][0]):
        med = {n: float(np.median([g[i]["median"] for g in got[n]])) for n in got}
        mn = {n: float(np.min([g[i]["min"] for g in got[n]])) for n in got}
        cpu = {n: float(np.median([g[i]["cpu"] for g in got[n]])) for n in got}
        table.append(dict(mask=row["mask"], lights=row["lights"], other=med["other"],
                          this=med["this"], min_other=mn["other"], min_this=mn["this"],
                          cpu_other=cpu["other"], cpu_this=cpu["this"]))
        print(f"{row['mask']:14s} {row['lights']:10s} {med['other'] * 1e3:8.1f} "
              f"{med['this'] * 1e3:8.1f} {med['this'] / med['other']:6.2f} "
              f"{mn['other'] * 1e3:8.1f} {mn['this'] * 1e3:8.1f} {mn['this'] / mn['other']:6.2f} "
              f"{cpu['other'] * 1e3:8.1f} {cpu['this'] * 1e3:8.1f} {cpu['this'] / cpu['other']:6.2f}")
    print("median: of the rounds' median wall; min: fastest wall run of all rounds (least "
          "disturbed by other load); cpu: median of the rounds' median process CPU")
    return table


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--big", type=int, default=2048, help="size of the memory run (0: skip)")
    ap.add_argument("--surface", default="sombrero")
    ap.add_argument("--blas-threads", default="1",
                    help="BLAS threads (set before numpy loads; 0 = library default)")
    ap.add_argument("--json", help="also write the rows to this file")
    ap.add_argument("--against", help="another source tree to compare with (A/B)")
    ap.add_argument("--rounds", type=int, default=5, help="A/B rounds (with --against)")
    a = ap.parse_args(argv)
    if a.against:
        against(a.against, a.size, max(5, a.runs), a.rounds, a.surface, a.blas_threads)
        return
    rows = bench(a.size, max(5, a.runs), a.surface)
    if a.json:
        keys = ("mask", "lights", "median", "ratio", "target", "matlab", "ne", "iterations",
                "min", "cpu")
        with open(a.json, "w") as fh:
            json.dump([dict(zip(keys, r)) for r in rows], fh, default=float)
    if a.big:
        bench_big(a.big, a.surface)


if __name__ == "__main__":
    main()
