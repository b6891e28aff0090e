"""Speed of weighted multi-zenith PS against plain PS (thesis Table 6.2 measured ~3x).

Runs at 512x512 on a TS-rendered sombrero2 with 16 lights (30x8+60x8, 5 % noise):
plain PS through ``psbench.solve.solve`` (least squares + split + residual) and
through the bare kernel (``kernel.ls`` + ``kernel.split``), then WPS for every weight
definition, weighted and binary. The runs are interleaved (one round = every case
once) and each case's median over the rounds is printed with its ratio to plain PS.
The machine is shared: absolute times are noisy, ratios less so.

Also times the subset masks: xNL and RA on the 16 images, CJ on 4 images (45x4).

Usage: python benchmarks/bench_wps.py [--size 512] [--rounds 9]
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--rounds", type=int, default=9)
    a = ap.parse_args(argv)

    from psbench.lights import layout
    from psbench.render import render
    from psbench.solve import kernel, solve, subset
    from psbench.solve.wps import wps
    from psbench.surfaces import make_surface

    surf = make_surface("sombrero2", size=a.size)
    lay = layout("30x8+60x8")
    I = render(surf, lay, model="ts", noise=0.05, seed=0).images
    lay4 = layout("45x4")
    I4 = render(surf, lay4, model="ts", noise=0.05, seed=0).images
    truth = surf.normals

    cases = {
        "PS solve()": lambda: solve(I, lay),
        "PS kernel ls+split": lambda: kernel.split(kernel.ls(I, lay.S)),
    }
    for w in ("None", "e", "eZsource", "eZsurface", "eZsourceZsurface", "oracle"):
        for b in (False, True):
            if w == "None" and b:
                continue
            kw = dict(truth_normals=truth) if w == "oracle" else {}
            cases[f"WPS {w}{' binary' if b else ''}"] = (
                lambda w=w, b=b, kw=kw: wps(I, lay, weight=w, binary=b, **kw))
    sub = {
        "xNL (16 images)": lambda: subset.xnl(I, lay.S, t_nl=0.02),
        "RA (16 images)": lambda: subset.ransac(I, lay.S),
        "CJ (4 images)": lambda: subset.cj(I4, lay4.S),
    }
    for f in list(cases.values()) + list(sub.values()):
        f()  # warm-up
    times = {k: [] for k in list(cases) + list(sub)}
    for _ in range(a.rounds):
        for name, f in list(cases.items()) + list(sub.items()):
            t = time.perf_counter()
            f()
            times[name].append(time.perf_counter() - t)
    med = {k: float(np.median(v)) for k, v in times.items()}
    base = med["PS solve()"]
    kbase = med["PS kernel ls+split"]
    print(f"size {a.size}x{a.size}, 16 images (30x8+60x8), medians of {a.rounds} interleaved rounds")
    print(f"{'case':32s} {'ms':>9s} {'x PS solve':>11s} {'x PS kernel':>12s}")
    for k in cases:
        print(f"{k:32s} {1e3 * med[k]:9.1f} {med[k] / base:11.2f} {med[k] / kbase:12.2f}")
    print()
    for k in sub:
        print(f"{k:32s} {1e3 * med[k]:9.1f}")


if __name__ == "__main__":
    main()
