"""The Chapter 7 forensic pipeline at 2048 x 2048: time per stage and peak memory.

Usage::

    python benchmarks/forensic_pipeline.py [--size 2048] [--runs 3] [--method LABEL]
                                           [--integrator poisson] [--blas-threads 1]
                                           [--profile N]

Each run is a fresh subprocess (so its peak RSS is its own): it builds the reference
(the sister case's true breech face, band-passed: a database entry, not timed as part of
the pipeline) and the evidence case, then times the pipeline stages

    acquire    render 16 lights (31x8+62x8) with cast shadows, Torrance-Sparrow brass,
               exposure to a mean of 75/255, read noise, 8-bit quantization
    solve      psbench.solve with the method (default weighted Th-Hi-Re-Sh)
    integrate  normals -> heights (default Poisson)
    compare    band-pass (16-250 um) the breech face, register against the reference
               over rotation and translation, CCFmax

and prints the median of every stage over the runs, the pipeline total against the
target (15 s), the peak RSS against 4 GiB, the machine load before and after, and a
baseline timed in the same child (a fixed 2048 x 2048 FFT workload: the ratio
pipeline / baseline is steadier than seconds on a shared machine).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys

TARGET_S, TARGET_GIB = 15.0, 4.0

CHILD = r"""
import json, resource, sys, time
import numpy as np
import scipy.fft as sfft
import psbench as ps
from psbench.forensic import make_cartridge, acquire, bandpass, register
from psbench.forensic.pipeline import INTEGRATORS, solve_kwargs

size, method, integrator = int(sys.argv[1]), sys.argv[2], sys.argv[3]
top = int(sys.argv[4])
out = {"cpu": {}}
cpu = [time.process_time()]

def lap(name, t0):
    out[name] = time.perf_counter() - t0
    c = time.process_time()
    out["cpu"][name] = c - cpu[0]
    cpu[0] = c
    return time.perf_counter()

a = np.random.default_rng(0).standard_normal((2048, 2048), dtype=np.float32)
t = time.perf_counter()
for _ in range(8):
    sfft.irfft2(sfft.rfft2(a, workers=-1), workers=-1)
t = lap("baseline_fft", t)
del a
ref = make_cartridge(size, gun=3, case=3)
bf_ref = ref.regions["breech_face"]
ref_f = bandpass(ref.height_um, bf_ref, pixel_size=ref.pixel_size)
t = lap("reference", t)
case = make_cartridge(size, gun=3, case=5)
t0 = t = lap("surface", t)
if top:                     # CPU-time profile of the pipeline stages (not of the baseline)
    import cProfile, io, pstats
    prof = cProfile.Profile(time.process_time)
    prof.enable()
acq = acquire(case, seed=1)
images, lights = acq.images, acq.lights
out["mean_level"] = acq.mean_level
del acq
t = lap("acquire", t)
res = ps.solve(images, lights, object_mask=case.object_mask, **solve_kwargs(method, case.pixel_size))
normals = res.normals
out["solve_timings"] = {k: round(v, 3) for k, v in res.timings.items()}
out["iterations"] = res.iterations
del res
t = lap("solve", t)
h = INTEGRATORS[integrator](normals, case.object_mask) * np.float32(case.pixel_size)
t = lap("integrate", t)
bf = case.regions["breech_face"]
m = register(ref_f, bandpass(h, bf, pixel_size=case.pixel_size), bf_ref, bf)
t = lap("compare", t)
out["pipeline"] = t - t0
if top:
    prof.disable()
    buf = io.StringIO()
    st = pstats.Stats(prof, stream=buf)
    st.sort_stats("tottime").print_stats(top)
    out["profile"] = buf.getvalue()
out["cpu"]["pipeline"] = sum(out["cpu"][k] for k in ("acquire", "solve", "integrate", "compare"))
out["ccf"] = m.ccf
out["ne"] = ps.normal_error(normals, case.normals, case.object_mask)
out["peak_rss_gib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2 ** 20
print(json.dumps(out))
"""

STAGES = ("surface", "acquire", "solve", "integrate", "compare", "pipeline", "baseline_fft")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=2048)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--method", default="weighted Th-Hi-Re-Sh",
                    help="a key of psbench.forensic.pipeline.METHODS")
    ap.add_argument("--integrator", default="poisson", help="poisson or bilateral")
    ap.add_argument("--profile", type=int, default=0, metavar="N",
                    help="print the N functions with the most CPU time (own time) of the "
                         "last run's pipeline (cProfile; adds overhead to that run's times)")
    ap.add_argument("--blas-threads", default="1",
                    help="OPENBLAS/OMP/MKL threads of the child (0: library default)")
    args = ap.parse_args(argv)
    env = dict(os.environ)
    if args.blas_threads != "0":
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            env[var] = args.blas_threads
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load0 = os.getloadavg()
    print(f"forensic pipeline, {args.size}x{args.size}, method={args.method!r}, "
          f"integrator={args.integrator!r}, {args.runs} runs, {cores} cores, "
          f"load {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}", flush=True)
    runs = []
    for i in range(args.runs):
        p = subprocess.run([sys.executable, "-c", CHILD, str(args.size), args.method,
                            args.integrator, str(args.profile if i == args.runs - 1 else 0)],
                           capture_output=True, text=True, env=env)
        if p.returncode:
            print(p.stderr, file=sys.stderr)
            return p.returncode
        r = json.loads(p.stdout.strip().splitlines()[-1])
        runs.append(r)
        print(f"  run {i + 1}: " + "  ".join(f"{k} {r[k]:.2f}s" for k in STAGES)
              + f"  peak {r['peak_rss_gib']:.2f} GiB  CCFmax {r['ccf']:.3f}  NE {r['ne']:.2f} deg"
              + f"  mean level {r['mean_level']:.1f}", flush=True)
    load1 = os.getloadavg()
    med = {k: statistics.median(r[k] for r in runs) for k in STAGES}
    cpu = {k: statistics.median(r["cpu"][k] for r in runs) for k in STAGES}
    peak = max(r["peak_rss_gib"] for r in runs)
    print("median per stage: wall s, process CPU s (user+system, all threads)")
    for k in STAGES:
        print(f"  {k:<12} {med[k]:8.2f} {cpu[k]:8.2f}")
    print(f"pipeline CPU time {cpu['pipeline']:.2f} s: on {cores} idle cores the wall "
          f"time would be about that or less")
    print(f"pipeline (acquire+solve+integrate+compare): {med['pipeline']:.2f} s "
          f"(target <= {TARGET_S:g} s: {'met' if med['pipeline'] <= TARGET_S else 'NOT met'}); "
          f"{med['pipeline'] / med['baseline_fft']:.1f} x the FFT baseline")
    print(f"peak RSS: {peak:.2f} GiB (target <= {TARGET_GIB:g} GiB: "
          f"{'met' if peak <= TARGET_GIB else 'NOT met'})")
    print(f"solve stages of the last run: {runs[-1]['solve_timings']}")
    print(f"load before {load0[0]:.2f}, after {load1[0]:.2f} (1-min averages)")
    if runs[-1].get("profile"):
        print("CPU profile of the last run's pipeline (own CPU seconds per function):")
        print(runs[-1]["profile"])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
