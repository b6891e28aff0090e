"""tsfit (per-pixel Lambert + Torrance–Sparrow fit): speed, memory, accuracy, real data.

Sections (all by default; pick with ``--only``):

``timing``
    sombrero2 at ``--size`` (512) with 16 lights (45x16), Torrance–Sparrow, cast
    shadows, 5 % noise: median wall and CPU time of ``--runs`` runs of plain least
    squares (mask None, the baseline), Th-Hi-Re-Sh, the registered ``robust``
    method, tsfit (default options: its start is ``robust``) and tsfit with the
    cheaper ``start="trimmed"``, all in the same run: with numba's default threads
    (a user's direct call) and pinned to one BLAS and numba thread (as a psbench run
    does). The first call's time in a fresh process (compiling the kernels into an
    empty cache, then loading them from it) is printed separately. With
    ``--baseline DIR`` (a psbench source tree, e.g. ``git archive main psbench | tar
    -x -C DIR``) the same tsfit run is timed in a fresh process on that tree and on
    this one. Target: <= 1 s at 512^2 x 16.
``memory``
    Peak resident memory of one tsfit run at ``--mem-size`` (2048) x 16 in a fresh
    process (``start="trimmed"`` and the default start), against the image stack.
``diligent``
    DiLiGenT cat and bear (all 96 images, ``$PSBENCH_DATA`` or ``--data``): NE and
    median times of psbench's least squares, ``robust`` and tsfit (default,
    ``start="trimmed"``, ``rho_s_mode="pixel"``) beside the published L2, ST14 and
    HS17 values. Target: <= 3 s per object.
``tables``
    Where the model is right and where not: tsfit against the best of the thesis's
    masks (None, Th, Hi-Re-Sh, Th-Hi-Re-Sh) at ``--table-size`` (128), lights 45x16
    and 30x8+60x8, noise 0 / 5 / 10 %, rendered with Torrance–Sparrow (the fitted
    model; with the per-pixel Cramer–Rao bound) and with Phong (a mismatch): the
    disc-only hemisphere and sombrero2 with self shadows only (the acceptance's
    scenes), the hemisphere on its ground plane and sombrero2 with cast shadows.

The machine may be shared: the load (``os.getloadavg``) is printed with every
section; compare ratios, and CPU times (on an idle machine, the wall time of
single-threaded work).

Usage::

    python benchmarks/tsfit.py [--only timing memory diligent tables] [--runs 5]
                               [--size 512] [--mem-size 2048] [--data DIR] [--quick]
                               [--baseline DIR]
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import psbench as ps
from psbench import registry
from psbench.solve.methods.tsfit import TsfitOptions, tsfit
from psbench.solve.methods.tsfit._start import resolve_start

from _tsfit_eval import noise_comparison, problem  # beside this script

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
    return ps.normal_error(n.astype(np.float32), truth, object_mask=mask)


def _robust(pr):
    spec = registry.get("methods", "robust")
    return spec.func(pr, spec.options())


def _methods(images, lay, mask, pr):
    out = [("None (LS)", lambda: ps.solve(images, lay, mask="None", object_mask=mask)),
           ("Th-Hi-Re-Sh", lambda: ps.solve(images, lay, mask="Th-Hi-Re-Sh",
                                             object_mask=mask))]
    if "robust" in registry.methods():
        out.append(("robust", lambda: _robust(pr)))
    out += [(f"tsfit (start {resolve_start('auto')})", lambda: tsfit(pr)),
            ("tsfit (start trimmed)", lambda: tsfit(pr, TsfitOptions(start="trimmed")))]
    return out


#: acceptance targets of issue 16 (seconds)
TARGET_512, TARGET_DILIGENT = 1.0, 3.0


def _verdict(value, target):
    return f"{value:.2f} s vs <= {target:.0f} s: {'MET' if value <= target else 'NOT MET'}"


def _threads():
    import numba
    from threadpoolctl import threadpool_info
    blas = sorted({i.get("num_threads") for i in threadpool_info() if i.get("user_api") == "blas"})
    return f"BLAS threads {blas}, numba threads {numba.get_num_threads()}"


_TIMING_CHILD = r"""
import json, sys, time, warnings
import numpy as np, psbench as ps
sys.path.insert(1, @HERE@)
from _tsfit_eval import problem
from psbench.solve.methods.tsfit import tsfit
warnings.simplefilter("ignore")
size, runs, pin = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3] == "1"
surf = ps.make_surface("sombrero2", size=size)
lay = ps.layout("45x16")
scene = ps.render(surf, lay, model="ts", noise=0.05, seed=0, shadows=True)
pr = problem(scene.images, lay, surf.object_mask)
t = time.perf_counter()
fit = tsfit(pr)
first = time.perf_counter() - t
import contextlib
ctx = contextlib.nullcontext()
if pin:
    from psbench.harness.run import pinned_threads
    ctx = pinned_threads()
wall, cpu = [], []
with ctx:
    for _ in range(runs):
        t, c = time.perf_counter(), time.process_time()
        fit = tsfit(pr)
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
n = fit.b / np.maximum(np.linalg.norm(fit.b, axis=2, keepdims=True), 1e-12)
ne = ps.normal_error(n.astype(np.float32), surf.normals, object_mask=surf.object_mask)
print(json.dumps(dict(first=first, wall=float(np.median(wall)), cpu=float(np.median(cpu)),
                      ne=float(ne))))
"""


def _child(code, argv, env=None, cwd=None):
    """Run ``code`` in a fresh interpreter; its last stdout line is JSON. ``cwd``: the
    directory whose ``psbench/`` it imports (``python -c`` puts it first on sys.path);
    ``@HERE@`` in ``code`` is this folder (the evaluation helpers)."""
    code = code.replace("@HERE@", repr(str(Path(__file__).resolve().parent)))
    out = subprocess.run([sys.executable, "-c", code, *map(str, argv)], capture_output=True,
                         text=True, check=True, env=env,
                         cwd=cwd or Path(__file__).resolve().parents[1])
    return json.loads(out.stdout.strip().splitlines()[-1])


def section_timing(args):
    import tempfile

    import numba
    from psbench.harness.run import pinned_threads
    print(f"\n## Timing: sombrero2 {args.size}^2 x 16 (45x16), TS, cast shadows, 5 % noise "
          f"[{load()}]")
    surf = ps.make_surface("sombrero2", size=args.size)
    lay = ps.layout("45x16")
    scene = ps.render(surf, lay, model="ts", noise=0.05, seed=0, shadows=True)
    mask = surf.object_mask
    pr = problem(scene.images, lay, mask)
    # first call in a fresh process: compiling the kernels (empty numba cache) and
    # loading them from the cache (what every later process pays)
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache)
        cold = _child(_TIMING_CHILD, [64, 1, 0], env)["first"]
        warm = _child(_TIMING_CHILD, [64, 1, 0], env)["first"]
    print(f"first tsfit call in a fresh process (64^2 x 16): {cold:.1f} s with an empty numba "
          f"cache (compilation), {warm:.2f} s with the kernels cached")
    tsfit(pr)  # warm-up
    print("| threads | method | median wall s | median CPU s | wall / LS | NE deg |")
    print("|---|---|---|---|---|---|")
    figures = {}
    for label, pinned in (("numba default", False), ("pinned (as psbench runs)", True)):
        ctx = pinned_threads() if pinned else contextlib.nullcontext()
        rows = []
        with ctx:
            threads = _threads()
            for name, fn in _methods(scene.images, lay, mask, pr):
                wall, cpu, res = timed(fn, args.runs)
                rows.append((name, wall, cpu, ne(res.b, surf.normals, mask), res))
        base = rows[0][1]
        for name, wall, cpu, e, res in rows:
            print(f"| {label}: {threads} | {name} | {wall:.3f} | {cpu:.3f} | "
                  f"{wall / base:.1f} | {e:.2f} |")
        figures[label] = rows
    default = next(r for r in figures["pinned (as psbench runs)"] if r[0].startswith("tsfit"))
    fit = default[4]
    cpu = {k: round(v, 3) for k, v in fit.info["cpu_timings"].items()}
    print(f"\ntsfit (default) CPU s per stage (last run, pinned): {cpu}; start="
          f"{fit.info['start']}; mean LM iterations {fit.iterations[mask].mean():.1f}; "
          f"propagated {fit.info['propagated']} pixels; converged "
          f"{100 * fit.converged[mask].mean():.2f} %  [{load()}]")
    if args.baseline:
        base = Path(args.baseline).resolve()
        code = _TIMING_CHILD.replace("warnings.simplefilter", "assert ps.__file__.startswith("
                                     "sys.argv[4]), ps.__file__\nwarnings.simplefilter")
        old = _child(code, [args.size, args.runs, 1, base], cwd=base)
        new = _child(code, [args.size, args.runs, 1, Path(__file__).resolve().parents[1]])
        print(f"\nbaseline {args.baseline} against this tree, each in a fresh process, "
              f"pinned to 1 thread, medians of {args.runs}: wall {old['wall']:.3f} -> "
              f"{new['wall']:.3f} s (x{old['wall'] / new['wall']:.2f}), CPU {old['cpu']:.3f} -> "
              f"{new['cpu']:.3f} s (x{old['cpu'] / new['cpu']:.2f}); NE {old['ne']:.4f} -> "
              f"{new['ne']:.4f} deg  [{load()}]")
    print("\n**Acceptance, tsfit default at 512^2 x 16**" if args.size == 512 else
          f"\n**tsfit default at {args.size}^2 x 16 (the acceptance is at 512^2)**")
    for label, rows in figures.items():
        r = next(r for r in rows if r[0].startswith("tsfit"))
        print(f"- {label}: median wall {_verdict(r[1], TARGET_512)} (CPU {r[2]:.2f} s)")
    print(f"  [{load()}; numba {numba.__version__}]")


_MEM_CHILD = r"""
import json, resource, sys, warnings
import numpy as np, psutil, psbench as ps
sys.path.insert(1, @HERE@)
from _tsfit_eval import problem
from psbench.solve.methods.tsfit import TsfitOptions, tsfit
warnings.simplefilter("ignore")
size, start = int(sys.argv[1]), sys.argv[2]
surf = ps.make_surface("sombrero2", size=size)
lay = ps.layout("45x16")
images = ps.render(surf, lay, model="ts", noise=0.05, seed=0, shadows=True).images
pr = problem(images, lay, surf.object_mask)
rss0 = psutil.Process().memory_info().rss
peak0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
fit = tsfit(pr, TsfitOptions(**({} if start == "default" else {"start": start})))
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps(dict(stack=images.nbytes, rss0=rss0, peak0=peak0, peak=peak,
                      cpu=fit.info["cpu_timings"], start=fit.info["start"])))
"""


def section_memory(args):
    print(f"\n## Memory: sombrero2 {args.mem_size}^2 x 16, one tsfit run in a fresh process "
          f"[{load()}]")
    print("| start | image stack MB | RSS before the fit MB | peak RSS MB | peak - before, "
          "x stack | fit CPU s |")
    print("|---|---|---|---|---|---|")
    for start in ("trimmed", "default"):
        out = subprocess.run([sys.executable, "-c", _MEM_CHILD, str(args.mem_size), start],
                             capture_output=True, text=True, check=True)
        r = json.loads(out.stdout.strip().splitlines()[-1])
        mb = 2 ** 20
        grow = (r["peak"] - r["rss0"]) / r["stack"] if r["peak"] > r["peak0"] else 0.0
        print(f"| {start if start != 'default' else r['start'] + ' (default)'} | "
              f"{r['stack'] / mb:.0f} | {r['rss0'] / mb:.0f} | {r['peak'] / mb:.0f} | "
              f"{grow:.1f} | {r['cpu']['total']:.1f} |")


def section_diligent(args):
    root = Path(args.data) if args.data else Path(os.environ.get(
        "PSBENCH_DATA", Path(__file__).resolve().parents[1].parent / "shared" / "data"))
    from psbench.harness.run import pinned_threads
    print(f"\n## DiLiGenT (96 images) [{load()}]")
    start = resolve_start("auto")
    verdicts = []
    print("NE in degrees; times are medians of --runs runs, wall / CPU seconds, least "
          "squares (LS, the baseline) timed in the same run")
    print("| object | psbench L2 | published L2 | ST14 | HS17 | robust | tsfit (start "
          f"{start}) | tsfit (start trimmed) | tsfit (rho_s per pixel) | LS wall / CPU s | "
          "robust wall / CPU s | tsfit wall / CPU s (x LS wall) | tsfit trimmed wall / CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for obj in ("cat", "bear"):
        folder = root / "diligent" / obj
        if not folder.is_dir():
            print(f"| {obj} | missing: {folder} |")
            continue
        ds = ps.io.read_dataset(folder)
        mask = ds.object_mask
        pr = problem(ds.images, ds.lights, mask)
        lw, lc, ls = timed(lambda: ps.solve(ds.images, ds.lights, mask="None",
                                            object_mask=mask), args.runs)
        rw, rc, rob = (timed(lambda: _robust(pr), args.runs) if "robust" in registry.methods()
                       else (float("nan"), float("nan"), ls))
        wall, cpu, fit = timed(lambda: tsfit(pr), args.runs)
        with pinned_threads():
            pw, pc, _ = timed(lambda: tsfit(pr), args.runs)
        verdicts.append(f"- {obj}: numba default ({_threads()}) median wall "
                        f"{_verdict(wall, TARGET_DILIGENT)}; pinned to 1 thread "
                        f"{_verdict(pw, TARGET_DILIGENT)} (CPU {pc:.2f} s)")
        tw, tc, fit_t = timed(lambda: tsfit(pr, TsfitOptions(start="trimmed")), args.runs)
        fit_px = tsfit(pr, TsfitOptions(rho_s_mode="pixel"))
        p = PUBLISHED[obj]
        e = lambda b: ne(b, ds.normals, mask)  # noqa: E731
        print(f"| {obj} | {e(ls.b):.2f} | {p['L2']} | {p['ST14']} | {p['HS17']} | "
              f"{e(rob.b):.2f} | {e(fit.b):.2f} | {e(fit_t.b):.2f} | {e(fit_px.b):.2f} | "
              f"{lw:.2f} / {lc:.2f} | {rw:.2f} / {rc:.2f} | {wall:.2f} / {cpu:.2f} "
              f"({wall / lw:.0f}x) | {tw:.2f} / {tc:.2f} |")
        print(f"|  | shared m = {fit.info['m']:.2f}, rho_s = {fit.info['rho_s']:.4f}, "
              f"converged {100 * fit.converged[mask].mean():.2f} %, CPU s per stage "
              f"{ {k: round(v, 2) for k, v in fit.info['cpu_timings'].items()} } |")
    print("\n**Acceptance, tsfit default on a 96-image DiLiGenT object**")
    print("\n".join(verdicts))
    print(f"  [{load()}]")


#: (surface, shadows) of the tables: the acceptance's scenes without cast shadows
#: (the disc-only hemisphere; sombrero2 with self shadows only) and both with cast
#: shadows (the hemisphere on its ground plane)
SCENES = (("semisphere_disc", "self"), ("sombrero2", "self"), ("semisphere", True),
          ("sombrero2", True))


def section_tables(args):
    noises = (0.0, 0.05) if args.quick else (0.0, 0.05, 0.1)
    for model in ("ts", "phong"):
        print(f"\n## {model.upper()}-rendered scenes, {args.table_size}^2 "
              f"[{load()}]")
        print("| surface | shadows | lights | noise | tsfit NE | per-pixel bound (CRB) | "
              "best mask | best mask NE | ratio | m | rho_s | converged % |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for surface, shadows in SCENES:
            for lights in ("45x16", "30x8+60x8"):
                rows = noise_comparison(surface, lights, noises, size=args.table_size,
                                        model=model, shadows=shadows, seed=0)
                for r in (r for r in rows if r["method"] == "tsfit"):
                    crb = "-" if not np.isfinite(r["crb_ne"]) else f"{r['crb_ne']:.2f}"
                    print(f"| {surface} | {shadows} | {lights} | {100 * r['noise']:.0f} % | "
                          f"{r['ne']:.2f} | "
                          f"{crb} | {r['best_mask']} | {r['best_mask_ne']:.2f} | "
                          f"{r['ratio']:.2f} | {r['m']:.2f} | {r['rho_s']:.3f} | "
                          f"{100 * r['converged']:.2f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sections = ("timing", "memory", "diligent", "tables")
    ap.add_argument("--only", nargs="+", choices=sections, default=sections)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--mem-size", type=int, default=2048)
    ap.add_argument("--table-size", type=int, default=128)
    ap.add_argument("--data", default=None)
    ap.add_argument("--baseline", default=None,
                    help="a psbench source tree (the directory holding psbench/) to time "
                         "against, e.g. an export of main")
    ap.add_argument("--quick", action="store_true", help="fewer runs, noise levels, smaller")
    args = ap.parse_args(argv)
    if args.quick:
        args.runs, args.size, args.table_size = 2, min(args.size, 256), min(args.table_size, 96)
        args.mem_size = min(args.mem_size, 512)
    warnings.simplefilter("ignore", RuntimeWarning)
    print(f"psbench {ps.__version__}, numpy {np.__version__}, {os.cpu_count()} CPUs, {load()}")
    for name in args.only:
        globals()[f"section_{name}"](args)


if __name__ == "__main__":
    main()
