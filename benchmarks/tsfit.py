"""tsfit (per-pixel Lambert + Torrance–Sparrow fit): speed, accuracy, real data.

Sections (all by default; pick with ``--only``):

``timing``
    sombrero2 at ``--size`` (512) with 16 lights (45x16), Torrance–Sparrow, cast
    shadows, 5 % noise: median wall and CPU time of ``--runs`` tsfit runs, beside
    plain least squares (mask None) and Th-Hi-Re-Sh timed in the same run (ratios).
    Target: <= 1 s at 512^2 x 16.
``diligent``
    DiLiGenT cat and bear (all 96 images, ``$PSBENCH_DATA`` or ``--data``): NE and
    median time of tsfit (default options, and ``rho_s_mode="pixel"``), of its start
    step (the registered ``robust`` method when there is one, else tsfit's private
    trimmed fallback) and of psbench's least squares, beside the published L2, ST14
    and HS17 values. Target: <= 3 s per object.
``tables``
    Where the model is right and where not: tsfit against the best of the thesis's
    masks (None, Th, Hi-Re-Sh, Th-Hi-Re-Sh) on semisphere and sombrero2 at
    ``--table-size`` (128), lights 45x16 and 30x8+60x8, noise 0 / 5 / 10 %,
    rendered with Torrance–Sparrow (the fitted model) and with Phong (a mismatch),
    cast shadows on.

The machine may be shared: the load (``os.getloadavg``) is printed with every
section; compare ratios. ``--blas-threads`` (default 1) is set before numpy loads
(multi-threaded OpenBLAS makes tsfit's many small matrix products much slower on a
busy machine).

Usage::

    python benchmarks/tsfit.py [--only timing diligent tables] [--runs 5] [--size 512]
                               [--data DIR] [--quick]
"""
from __future__ import annotations

import argparse
import os
import sys
import time
import warnings
from pathlib import Path


def _blas_threads(argv):
    n = "1"
    for i, a in enumerate(argv):
        if a == "--blas-threads" and i + 1 < len(argv):
            n = argv[i + 1]
        elif a.startswith("--blas-threads="):
            n = a.split("=", 1)[1]
    if n != "0":
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ[var] = n
    return n


BLAS_THREADS = _blas_threads(sys.argv) if __name__ == "__main__" else None

import numpy as np  # noqa: E402

import psbench as ps  # noqa: E402
from psbench import registry  # noqa: E402
from psbench.solve.methods._tsfit_eval import noise_comparison, problem  # noqa: E402
from psbench.solve.methods._tsstart import resolve_start  # noqa: E402
from psbench.solve.methods.tsfit import TsfitOptions, tsfit  # noqa: E402

#: published mean angular errors (degrees): DiLiGenT paper (L2, ST14) and HS17
PUBLISHED = {"cat": {"L2": 8.41, "ST14": 6.12, "HS17": 4.9},
             "bear": {"L2": 8.39, "ST14": 6.12, "HS17": 5.6}}


def load():
    return "load %.2f %.2f %.2f" % os.getloadavg()


def timed(fn, runs):
    """(median wall, median CPU, last result) of ``runs`` calls."""
    wall, cpu, out = [], [], None
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return float(np.median(wall)), float(np.median(cpu)), out


def ne(b, truth, mask):
    n = b / np.maximum(np.linalg.norm(b, axis=2, keepdims=True), 1e-12)
    return ps.normal_error(n.astype(np.float32), truth, mask)


def section_timing(args):
    print(f"\n## Timing: sombrero2 {args.size}^2 x 16 (45x16), TS, cast shadows, 5 % noise "
          f"[{load()}, BLAS threads {BLAS_THREADS}]")
    surf = ps.make_surface("sombrero2", size=args.size)
    lay = ps.layout("45x16")
    scene = ps.render(surf, lay, model="ts", noise=0.05, seed=0, shadows=True)
    pr = problem(scene.images, lay, surf.object_mask)
    rows = []
    for name, fn in [
            ("None (LS)", lambda: ps.solve(scene.images, lay, mask="None", object_mask=surf.object_mask)),
            ("Th-Hi-Re-Sh", lambda: ps.solve(scene.images, lay, mask="Th-Hi-Re-Sh",
                                              object_mask=surf.object_mask)),
            ("tsfit", lambda: tsfit(pr))]:
        wall, cpu, res = timed(fn, args.runs)
        b = res.b
        rows.append((name, wall, cpu, ne(b, surf.normals, surf.object_mask), res))
    base = rows[0][1]
    print("| method | median wall s | median CPU s | x None | NE deg |")
    print("|---|---|---|---|---|")
    for name, wall, cpu, e, _ in rows:
        print(f"| {name} | {wall:.3f} | {cpu:.3f} | {wall / base:.1f} | {e:.2f} |")
    fit = rows[-1][4]
    st = {k: round(v, 3) for k, v in fit.info["timings"].items()}
    print(f"tsfit stages (last run, wall s): {st}; start={fit.info['start']}; "
          f"mean LM iterations {fit.iterations[surf.object_mask].mean():.1f}; "
          f"converged {100 * fit.converged[surf.object_mask].mean():.2f} %  [{load()}]")


def section_diligent(args):
    root = Path(args.data) if args.data else Path(os.environ.get(
        "PSBENCH_DATA", Path(__file__).resolve().parents[1].parent / "shared" / "data"))
    print(f"\n## DiLiGenT (96 images) [{load()}]")
    start = resolve_start("auto")
    print(f"tsfit's start step here: {start!r} "
          f"({'registered robust method' if start == 'robust' else 'private fallback'})")
    print("| object | psbench L2 | published L2 | ST14 | HS17 | start (" + start + ") | "
          "tsfit | tsfit rho_s per pixel | tsfit median s | tsfit CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for obj in ("cat", "bear"):
        folder = root / "diligent" / obj
        if not folder.is_dir():
            print(f"| {obj} | missing: {folder} |")
            continue
        ds = ps.io.read_dataset(folder)
        pr = problem(ds.images, ds.lights, ds.mask)
        ls = ps.solve(ds.images, ds.lights, mask="None", object_mask=ds.mask)
        wall, cpu, fit = timed(lambda: tsfit(pr), args.runs)
        fit_px = tsfit(pr, TsfitOptions(rho_s_mode="pixel"))
        if start == "robust":
            spec = registry.get("methods", "robust")
            b_start = spec.func(pr, spec.options()).b
        else:
            from psbench.solve.methods._tsstart import start_weights
            idx = np.flatnonzero(ds.mask.ravel())
            k = ds.images.shape[0]
            I = np.ascontiguousarray(ds.images.reshape(k, -1)[:, idx])
            b, _ = start_weights(pr, "trimmed", idx, I, np.ones(I.shape, bool))
            b_start = np.zeros((ds.mask.size, 3), np.float32)
            b_start[idx] = b.T
            b_start = b_start.reshape(*ds.mask.shape, 3)
        p = PUBLISHED[obj]
        print(f"| {obj} | {ne(ls.b, ds.normals, ds.mask):.2f} | {p['L2']} | {p['ST14']} | "
              f"{p['HS17']} | {ne(b_start, ds.normals, ds.mask):.2f} | "
              f"{ne(fit.b, ds.normals, ds.mask):.2f} | {ne(fit_px.b, ds.normals, ds.mask):.2f} | "
              f"{wall:.2f} | {cpu:.2f} |")
        print(f"|  | shared m = {fit.info['m']:.2f}, rho_s = {fit.info['rho_s']:.4f}, "
              f"converged {100 * fit.converged[ds.mask].mean():.2f} % |")
    print(f"[{load()}]")


def section_tables(args):
    noises = (0.0, 0.05) if args.quick else (0.0, 0.05, 0.1)
    for model in ("ts", "phong"):
        print(f"\n## {model.upper()}-rendered scenes, {args.table_size}^2, cast shadows "
              f"[{load()}]")
        print("| surface | lights | noise | tsfit NE | best mask | best mask NE | ratio | "
              "m | rho_s | converged % |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for surface in ("semisphere", "sombrero2"):
            for lights in ("45x16", "30x8+60x8"):
                rows = noise_comparison(surface, lights, noises, size=args.table_size,
                                        model=model, shadows=True, seed=0)
                for r in (r for r in rows if r["method"] == "tsfit"):
                    print(f"| {surface} | {lights} | {100 * r['noise']:.0f} % | {r['ne']:.2f} | "
                          f"{r['best_mask']} | {r['best_mask_ne']:.2f} | {r['ratio']:.2f} | "
                          f"{r['m']:.2f} | {r['rho_s']:.3f} | {100 * r['converged']:.2f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", nargs="+", choices=("timing", "diligent", "tables"),
                    default=("timing", "diligent", "tables"))
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--table-size", type=int, default=128)
    ap.add_argument("--data", default=None)
    ap.add_argument("--quick", action="store_true", help="fewer runs, noise levels, smaller")
    ap.add_argument("--blas-threads", default="1")
    args = ap.parse_args(argv)
    if args.quick:
        args.runs, args.size, args.table_size = 2, min(args.size, 256), min(args.table_size, 96)
    warnings.simplefilter("ignore", RuntimeWarning)
    print(f"psbench {ps.__version__}, numpy {np.__version__}, {os.cpu_count()} CPUs, {load()}")
    for name in args.only:
        globals()[f"section_{name}"](args)


if __name__ == "__main__":
    main()
