"""Interreflections: render speed, accuracy against references, SR speed and the
preliminary ``interreflection`` table.

Sections (all by default; pick with --only):

speed     render(..., bounces=1) of the cup at --size^2 x 16 lights (30x8+60x8),
          Lambert and Torrance-Sparrow, median of --repeats runs, wall and CPU time,
          ratio to the direct render (bounces=0) timed in the same run; the numpy
          fallback once (engine comparison). Target: <= 30 s at 512^2 x 16.
sr        ps.solve(mask="SR") at --size^2 x 16 (Lambert cup, one bounce): median wall/CPU time,
          ratio to plain least squares and to Th-Hi-Re-Sh in the same run. Target: <= 10 s.
accuracy  one bounce against the closed form of a Lambert spherical cap (all sizes
          and sampling densities) and against the brute-force patch sum on a V-groove.
table     NE (mean, deg) and solve time of None, Th-Hi-Re-Sh and the SR variants on the
          concave surfaces, rendered without and with one bounce.

Timings are noisy on a shared machine: the load (``os.getloadavg``) is printed, and
the CPU time over all threads is less inflated by other processes than wall time.

Usage: python benchmarks/bench_interreflect.py [--only speed sr accuracy table]
       [--size 512] [--repeats 3] [--table-size 256]
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

import psbench as ps
from psbench.render._interreflect import Specular, secondary
from psbench.render._interreflect_ref import reference
from psbench.surfaces.cup import cup, cup_geometry
from psbench.surfaces.vgroove import vgroove


def _mask(s):
    return np.asarray(s.object_mask)


def _time(fn, repeats):
    wall, cpu, out = [], [], None
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return statistics.median(wall), statistics.median(cpu), out


def _load():
    return "load %.1f %.1f %.1f" % os.getloadavg()


def speed(size, repeats):
    print(f"\n== render speed: cup {size}^2 x 16 lights, bounces=1, 24 azimuths ({_load()})")
    surf, lay = cup(size), ps.layout("30x8+60x8")
    ps.render(cup(32), lay, bounces=1)  # compile / load the kernel cache first
    for model in ("lambert", "ts"):
        w0, c0, _ = _time(lambda: ps.render(surf, lay, model=model), repeats)
        w1, c1, _ = _time(lambda: ps.render(surf, lay, model=model, bounces=1), repeats)
        print(f"{model:8s} bounces=0 {w0:7.3f} s (cpu {c0:6.2f})   bounces=1 {w1:7.2f} s "
              f"(cpu {c1:6.2f})   ratio {w1 / w0:6.0f}x   target <= 30 s: "
              f"{'met' if w1 <= 30 else 'MISSED'}")
    d = ps.render(surf, lay, model="lambert")
    m = _mask(surf)
    for engine in ("numba", "numpy"):
        w, c, _ = _time(lambda: secondary(surf.height, surf.normals, d.images, object_mask=m,
                                          engine=engine), 1)
        print(f"engine {engine:6s} (Lambert secondary light alone, 1 run): {w:7.2f} s wall, "
              f"{c:7.2f} s cpu")
    print(_load())


def sr(size, repeats):
    print(f"\n== SR solve: Lambert cup {size}^2 x 16 lights, one bounce ({_load()})")
    surf, lay = cup(size), ps.layout("30x8+60x8")
    m = _mask(surf)
    scene = ps.render(surf, lay, model="lambert", bounces=1)
    w0, c0, r0 = _time(lambda: ps.solve(scene.images, lay, object_mask=m), repeats)
    w1, c1, r1 = _time(lambda: ps.solve(scene.images, lay, mask="Th-Hi-Re-Sh", object_mask=m),
                       repeats)
    w2, c2, f = _time(lambda: ps.solve(scene.images, lay, mask="SR", object_mask=m), repeats)
    ne = [ps.normal_error(x.normals, surf.normals, object_mask=m) for x in (r0, r1, f)]
    print(f"None        {w0:7.3f} s (cpu {c0:6.2f})  NE {ne[0]:6.2f}")
    print(f"Th-Hi-Re-Sh {w1:7.3f} s (cpu {c1:6.2f})  NE {ne[1]:6.2f}")
    print(f"SR          {w2:7.3f} s (cpu {c2:6.2f})  NE {ne[2]:6.2f}  rounds {f.iterations}  "
          f"{w2 / w0:.0f}x None, {w2 / w1:.1f}x Th-Hi-Re-Sh; target <= 10 s: "
          f"{'met' if w2 <= 10 else 'MISSED'}")
    print("SR stage times (last run):", {k: round(v, 2) for k, v in f.timings.items()})
    print(_load())


def accuracy():
    print(f"\n== accuracy ({_load()})")
    print("Lambert cup, one bounce vs closed form rho sum(B dA) / (4 pi R^2); interior "
          "(2 px from the rim); 4 lights at 30/60 deg")
    print(f"{'size':>5} {'azimuths':>8} {'mean err':>9} {'p5':>8} {'p95':>8} {'time s':>7}")
    lay = ps.layout("30x2+60x2")
    for size in (64, 128, 256, 512):
        surf = cup(size)
        m = _mask(surf)
        d = ps.render(surf, lay, model="lambert")
        R, a, _ = cup_geometry(size)
        ref = (d.images[:, m] / surf.normals[..., 2][m]).sum(1) / (4 * np.pi * R * R)
        y, x = np.mgrid[:size, :size] - (size - 1) / 2
        inner = m & (np.hypot(x, y) < a - 2)
        for samples in (16, 24, 48):
            if size == 512 and samples == 48:
                continue
            t = time.perf_counter()
            out = secondary(surf.height, surf.normals, d.images, object_mask=m, samples=samples)
            t = time.perf_counter() - t
            rel = out[:, inner] / ref[:, None] - 1
            print(f"{size:5d} {samples:8d} {rel.mean():+9.4f} {np.percentile(rel, 5):+8.4f} "
                  f"{np.percentile(rel, 95):+8.4f} {t:7.2f}")
    print("\nV-groove vs brute-force patch sum (sub=2), faces 2 px from rims and apex, "
          "3 lights at 45 deg, 32 azimuths")
    print(f"{'size':>5} {'model':>8} {'mean err':>9} {'p90 |err|':>10} {'apex col':>9}")
    lay = ps.layout("45x3")
    for size in (32, 48, 64):
        surf = vgroove(size)
        m = _mask(surf)
        xs = np.abs(np.arange(size) - (size - 1) / 2)
        for model in ("lambert", "ts"):
            d = ps.render(surf, lay, model=model)
            lit = ~(d.self_shadow | d.cast_shadow) & m[None]
            spec = None if model == "lambert" else Specular(model, 1.0, 2.0, 20.0,
                                                            lay.directions, lay.power, lit)
            diff = d.images if model == "lambert" else d.diffuse
            ref = reference(surf.height, surf.normals, diff, object_mask=m, specular=spec,
                            visibility=False, sub=2)
            out = secondary(surf.height, surf.normals, diff, object_mask=m, specular=spec,
                            samples=32)
            rows = slice(2, size - 2)
            face = (xs > 2.5) & m[0] & (xs < xs[m[0]].max() - 2)
            r, o = ref[:, rows][:, :, face], out[:, rows][:, :, face]
            big = r > 0.05 * r.max()
            rel = (o - r)[big] / r[big]
            apex = (xs < 1) & m[0]
            ra, oa = ref[:, rows][:, :, apex], out[:, rows][:, :, apex]
            print(f"{size:5d} {model:>8} {rel.mean():+9.4f} {np.percentile(np.abs(rel), 90):10.4f} "
                  f"{oa.sum() / ra.sum() - 1:+9.3f}")
    print(_load())


def table(size):
    print(f"\n== preliminary interreflection table: {size}^2, 30x8+60x8, noiseless ({_load()})")
    lay = ps.layout("30x8+60x8")
    rows = [("None", lambda im, m: ps.solve(im, lay, object_mask=m)),
            ("Th-Hi-Re-Sh", lambda im, m: ps.solve(im, lay, mask="Th-Hi-Re-Sh", object_mask=m)),
            ("SR", lambda im, m: ps.solve(im, lay, mask="SR", object_mask=m)),
            ("SR weighted", lambda im, m: ps.solve(im, lay, mask="SR", object_mask=m,
                                                   weighted=True)),
            ("SR mask only", lambda im, m: ps.solve(im, lay, mask="SR", object_mask=m,
                                                    sr_correct=False)),
            ("SR 2 bounces", lambda im, m: ps.solve(im, lay, mask="SR", object_mask=m,
                                                    sr_bounces=2)),
            ("Th-Hi-Re-Sh-SR", lambda im, m: ps.solve(im, lay, mask="Th-Hi-Re-Sh-SR",
                                                      object_mask=m))]
    head = f"{'surface':8s} {'model':8s} {'bounces':>7s} | " + " | ".join(
        f"{n:>15s}" for n, _ in rows)
    print(head)
    print("-" * len(head))
    for surf in (cup(size), vgroove(size)):
        m = _mask(surf)
        for model in ("lambert", "ts"):
            for b in (0, 1, 2):
                scene = ps.render(surf, lay, model=model, bounces=b)
                frac = float(scene.secondary_fraction[:, m].mean())
                cells = []
                for _, fn in rows:
                    t = time.perf_counter()
                    r = fn(scene.images, m)
                    t = time.perf_counter() - t
                    cells.append(f"{ps.normal_error(r.normals, surf.normals, object_mask=m):6.2f} {t:6.1f}s")
                print(f"{surf.name:8s} {model:8s} {b:7d} | " + " | ".join(f"{c:>15s}" for c in cells)
                      + f"   (mean secondary fraction {frac:.3f})", flush=True)
    print("cells: mean NE in degrees, solve time;", _load())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="+", default=["speed", "sr", "accuracy", "table"],
                    choices=["speed", "sr", "accuracy", "table"])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--table-size", type=int, default=256)
    a = ap.parse_args(argv)
    if "speed" in a.only:
        speed(a.size, a.repeats)
    if "sr" in a.only:
        sr(a.size, a.repeats)
    if "accuracy" in a.only:
        accuracy()
    if "table" in a.only:
        table(a.table_size)


if __name__ == "__main__":
    main()
