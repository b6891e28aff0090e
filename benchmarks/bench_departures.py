"""Render departures (GGX, textures, camera, light errors, near lights): time and memory.

Each configuration renders the sombrero under 16 lights (30x8+60x8, cast shadows, noise
0.05) in a fresh process, so that its peak RSS is its own; prints the median wall time
of the repeats, the ratio to the plain Torrance-Sparrow render measured in the same run,
and the peak RSS beside the size of the Scene's stacks (images + 3 truth stacks).

Usage: python benchmarks/bench_departures.py [--size 2048] [--repeats 2]
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

CONFIGS = {
    "ts (baseline)": {},
    "ggx": {"model": "ggx", "roughness": 0.2},
    "albedo_texture + second_material": {"albedo_texture": 0.5,
                                         "second_material": {"rho_s": 0.3, "m": 6.0}},
    "camera (ambient, saturation, gamma, 8-bit)": {"ambient": 0.02, "saturation": 0.7,
                                                   "gamma": 2.2, "quantize": 8},
    "light_error + power_error": {"light_error": 2.0, "power_error": 0.1},
    "near lights (light_distance, falloff)": {"light_distance": 3.0, "falloff": True},
}

_CHILD = """
import json, resource, statistics, sys, time
import psbench as ps
size, reps, kw = int(sys.argv[1]), int(sys.argv[2]), json.loads(sys.argv[3])
surf = ps.make_surface("sombrero", size=size)
lay = ps.layout("30x8+60x8")
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
times = []
for _ in range(reps):
    t = time.perf_counter()
    sc = ps.render(surf, lay, noise=0.05, **kw)
    times.append(time.perf_counter() - t)
    del sc
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
print(json.dumps({"median": statistics.median(times), "peak": peak, "before": base}))
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args(argv)
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    stacks = 16 * args.size ** 2 * (4 + 3) / 2 ** 20
    print(f"sombrero {args.size}^2, 30x8+60x8, cast shadows, noise 0.05; median of "
          f"{args.repeats}; {os.cpu_count()} cores, load average {load}; the Scene's "
          f"stacks: {stacks:.0f} MB")
    base = None
    for name, kw in CONFIGS.items():
        out = subprocess.run([sys.executable, "-c", _CHILD, str(args.size), str(args.repeats),
                              json.dumps(kw)], capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        base = base or r["median"]
        print(f"  {name:45s} {r['median']:7.2f} s  ({r['median'] / base:4.2f}x ts)  peak RSS "
              f"{r['peak']:6.0f} MB (surface and imports {r['before']:5.0f} MB)")


if __name__ == "__main__":
    main()
