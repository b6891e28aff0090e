"""Render speed: 16 lights (30x8+60x8), Torrance–Sparrow, cast shadows, all ground truth.

Prints the median of several runs at 512^2 and 2048^2 and ratios against
baselines measured in the same run (the same render without shadows, and the
shadow map alone). Targets: <= 0.5 s at 512^2, <= 8 s at 2048^2 on a 2-core
machine. Figures are noisy on a shared machine: compare ratios, and the CPU
time (process time over all threads), which the load from other processes
inflates much less than wall time.

Usage: python benchmarks/bench_render.py [--sizes 512 2048] [--repeats 5 3]
"""
from __future__ import annotations

import argparse
import os
import resource
import statistics
import time

import numpy as np

from psbench.lights import layout
from psbench.render import render
from psbench.render.shadowmap import shadow_map

TARGETS = {512: 0.5, 2048: 8.0}


def _surface(size):
    try:
        from psbench.surfaces import make_surface
        return make_surface("sombrero", size=size), "sombrero"
    except Exception:  # surfaces module missing: sombrero-like height inline
        from types import SimpleNamespace
        r = np.arange(size)
        x = (r[None, :] - (size - 1) / 2) / (size / 2)
        y = ((size - 1) / 2 - r[:, None]) / (size / 2)
        rr = np.hypot(x, y) * 3 * np.pi + 1e-9
        h = (np.sin(rr) / rr * size * 0.15).astype(np.float32)
        gy, gx = np.gradient(h)
        n = np.stack([-gx, gy, np.ones_like(h)], -1)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        return SimpleNamespace(height=h, mask=np.ones((size, size), bool),
                               normals=n.astype(np.float32)), "inline sombrero"


def _median(fn, repeats):
    """Median wall time, the wall times, and the median CPU time (all threads)."""
    times, cpu = [], []
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return statistics.median(times), times, statistics.median(cpu)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 2048])
    ap.add_argument("--repeats", type=int, nargs="+", default=[5, 3])
    ap.add_argument("--lights", default="30x8+60x8")
    args = ap.parse_args(argv)
    reps = args.repeats + [args.repeats[-1]] * (len(args.sizes) - len(args.repeats))
    lay = layout(args.lights)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    print(f"lights {lay.name} (k={lay.k}), model ts, cast shadows + highlight/self/cast truth, "
          f"noise 0.05; {os.cpu_count()} cores, load average {load}")
    for size, rep in zip(args.sizes, reps):
        surf, name = _surface(size)
        render(surf, lay)  # warm-up (imports, caches)
        full, t_full, c_full = _median(lambda: render(surf, lay, shadows=True, noise=0.05), rep)
        base, _, c_base = _median(lambda: render(surf, lay, shadows=False, noise=0.05), rep)
        smap, _, c_smap = _median(lambda: shadow_map(surf.height, lay.directions, bias=0.05), rep)
        target = TARGETS.get(size)
        verdict = "" if target is None else (
            f"  target <= {target:g} s: wall {'met' if full <= target else 'MISSED'}, "
            f"CPU {'met' if c_full <= target else 'MISSED'}")
        print(f"{size}x{size} ({name}), median of {rep}:")
        print(f"  render ts + cast shadows + truth : {full:.3f} s wall, {c_full:.3f} s CPU  "
              f"(runs {', '.join(f'{t:.3f}' for t in t_full)}){verdict}")
        print(f"  render ts, shadows=False (base)  : {base:.3f} s wall, {c_base:.3f} s CPU  "
              f"-> ratio full/base {full / base:.2f}x wall, {c_full / c_base:.2f}x CPU")
        print(f"  shadow_map alone, {lay.k} lights     : {smap:.3f} s wall, {c_smap:.3f} s CPU  "
              f"({smap / lay.k * 1e3:.1f} ms/light wall)")
        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        out_mb = lay.k * size * size * (4 + 3) / 2 ** 20
        print(f"  peak RSS of this process so far  : {peak:.0f} MB "
              f"(the Scene's images + 3 truth stacks: {out_mb:.0f} MB)")


if __name__ == "__main__":
    main()
