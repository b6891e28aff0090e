"""Speed of psbench.integrate at 512² and 2048² (median of several runs).

Run: ``python benchmarks/bench_integrate.py [--repeat 5] [--sizes 512 2048]``.
Cases: a smooth full-frame surface (no mask: one DCT solve for "poisson") and
a hemisphere-with-notch under a mask (exact masked CG for "poisson"). Prints
median wall and CPU seconds (CPU summed over threads) and the CPU ratio
against "poisson-dct" (one DCT solve), the baseline.
The machine is shared: figures are noisy; compare ratios, not absolutes.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from psbench.integrate import integrate


def case(N, masked, seed=0):
    c = np.arange(N)
    x = c[None, :] - (N - 1) / 2 + 0.0 * c[:, None]
    y = (N - 1) / 2 - c[:, None] + 0.0 * c[None, :]
    R = 0.4 * N
    rr = x ** 2 + y ** 2
    disc = rr < R ** 2
    n = np.zeros((N, N, 3))
    n[..., 2] = 1.0
    if masked:
        n[disc, 0] = x[disc] / R
        n[disc, 1] = y[disc] / R
        n[disc, 2] = np.sqrt(np.maximum(R ** 2 - rr[disc], 0)) / R
        object_mask = disc & ~((np.abs(y) < N / 64) & (x > 0))  # notch: a harder silhouette
    else:
        k = 2 * np.pi / N
        p = 20 * k * np.cos(3 * k * x) * np.cos(2 * k * y) * 3
        q = -20 * k * np.sin(3 * k * x) * np.sin(2 * k * y) * 2
        n = np.dstack([-p, -q, np.ones_like(p)])
        object_mask = None
    rng = np.random.default_rng(seed)
    n = n + 0.02 * rng.normal(size=n.shape)  # estimated normals are noisy
    return n.astype(np.float32), object_mask


def bench(fn, repeat):
    """Median wall and CPU (all threads) seconds; CPU time is less sensitive to load."""
    fn()  # warm-up (FFT plans, imports)
    wall, cpu = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return float(np.median(wall)), float(np.median(cpu))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 2048])
    ap.add_argument("--sparse", action="store_true", help="also time poisson-sparse (slow)")
    a = ap.parse_args(argv)
    methods = ["poisson-dct", "poisson", "fc"] + (["poisson-sparse"] if a.sparse else [])
    print(f"{'size':>6} {'case':>8} {'method':>15} {'wall s':>9} {'cpu s':>9} {'x dct':>7}")
    for N in a.sizes:
        for masked in (False, True):
            n, m = case(N, masked)
            base = None
            for meth in methods:
                if meth == "poisson-sparse" and N > 1024:
                    continue
                rep = 1 if meth == "poisson-sparse" else a.repeat
                t, c = bench(lambda: integrate(n, object_mask=m, integrator=meth), rep)
                base = c if base is None else base
                print(f"{N:>6} {'masked' if masked else 'full':>8} {meth:>15} {t:>9.4f} "
                      f"{c:>9.4f} {c / base:>7.2f}", flush=True)


if __name__ == "__main__":
    main()
