"""Robust methods beside the thesis's masks: NE and time on real and synthetic data.

Cases (each method with its default options, one setting for all objects):

* DiLiGenT ``cat`` and ``bear`` (``$PSBENCH_DATA/diligent`` or ``--data``) with all 96
  lights, and with the 16-light rig subset: the lights nearest to the rings
  ``30x8+60x8``, picked greedily without reuse, most certain match first
  (:func:`psbench.harness.run.select_lights`). DiLiGenT's lights stop at ~43 degrees
  zenith, so the "60" ring is matched by the outermost lights.
* ``sombrero2`` at 512^2, 45x16 lights, Torrance-Sparrow with self and cast shadows,
  5 % noise (seed 0).

Rows: None (L2), the thesis's masks Th and Th-Hi-Re-Sh (``psbench.solve``), and every
robust method (trim, huber, cauchy, tukey, l1, sbl, rpca, robust) on all observations
(mask None); ``--compose Th`` also runs each method on the observations Th keeps.
Robust methods are called as the masked-PS engine will call them: a
:class:`psbench.solve.base.Problem` whose start (masked least squares) is computed on
first use inside the timed call. NE: mean angular error in degrees over the object
mask; time: median wall time of ``--repeat`` runs (default 5, after one warm-up call
that compiles the kernels) of the whole call, with
the ratio to None's time of the same case, and the median process CPU time (on a
busy shared machine the steadier figure: wall time there includes waiting for a
core). BLAS and numba run single-threaded by default (``--blas-threads``,
``--threads``), as psbench's runs do (the robust methods' kernels are serial anyway). The last table states, per acceptance target of
the robust methods, the measured value, the target and whether it is met.

Usage::

    python benchmarks/robust.py [--data DIR] [--cases cat96 cat16 bear96 bear16 sombrero]
                                [--methods ...] [--repeat 5] [--threads 1] [--compose Th]
                                [--th-study]

``--th-study`` adds a table on why the thesis's Th mask fails on real photographs with
few lights (what Eq. 3.2 marks per DiLiGenT light subset).
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

MASKS = ["None", "Th", "Th-Hi-Re-Sh"]
METHODS = ["trim", "huber", "cauchy", "tukey", "l1", "sbl", "rpca", "robust", "tsfit"]
CASES = ["cat96", "cat16", "bear96", "bear16", "sombrero"]
RIG = "30x8+60x8"
#: wall time of the warm-up call of the last :func:`timed`
FIRST_CALL = []
#: (case, method) -> (NE, median wall s, median CPU s, first call s) of the default rows
RESULTS = {}
#: acceptance targets of the robust methods: (case, method, quantity, limit)
TARGETS = [("sombrero", "trim", "time", 0.05)] + [
    ("sombrero", m, "time", 0.3) for m in ("huber", "cauchy", "tukey")] + [
    (c, "robust", "time", 1.0) for c in ("cat96", "bear96")] + [
    ("cat96", "robust", "NE", 6.3), ("bear96", "robust", "NE", 5.9),
    ("sombrero", "robust", "NE", 6.3)] + [
    (c, m, "time", lim) for c in ("cat96", "bear96") for m, lim in
    (("l1", 2.0), ("sbl", 2.0), ("rpca", 5.0))]


def data_root(arg):
    if arg:
        return Path(arg)
    env = os.environ.get("PSBENCH_DATA")
    return Path(env) if env else Path(__file__).resolve().parents[1].parent / "shared" / "data"


def load_case(name, root):
    """(images, lights, object_mask, truth normals, label)."""
    if name == "sombrero":
        surf = ps.make_surface("sombrero2", size=512)
        lay = ps.layout("45x16")
        sc = ps.render(surf, lay, model="ts", shadows=True, noise=0.05, seed=0)
        return sc.images, lay, surf.object_mask, surf.normals, "sombrero2 512^2 45x16 TS 5%"
    from psbench.harness.run import select_lights
    from psbench.io import read_dataset

    obj, count = name[:-2], name[-2:]
    ds = read_dataset(root / obj)
    images, lights = ds.images, ds.lights
    if count == "16":
        images, lights = select_lights(images, lights, RIG)
    return images, lights, ds.object_mask, ds.normals, f"{obj} {images.shape[0]} lights"


def _problem(images, lights, valid, omask):
    from psbench.solve import kernel
    from psbench.solve.base import Problem

    k = images.shape[0]
    f = images.reshape(k, -1)
    scale = float((f.max(axis=1) - f.min(axis=1)).mean()) or 1.0
    S = lights.S
    return Problem(images=images, lights=lights, valid=valid, object_mask=omask, scale=scale,
                   _start=lambda: (kernel.ls(images, S) if valid.all()
                                   else kernel.wls(images, S, valid)))


def timed(fn, repeat):
    """(result, median wall seconds, median process CPU seconds) of ``repeat`` calls
    after one warm-up call (compilation of the kernels on first use; its wall time is
    kept in ``FIRST_CALL``)."""
    t = time.perf_counter()
    out = fn()
    FIRST_CALL.append(time.perf_counter() - t)
    times, cpu = [], []
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return out, float(np.median(times)), float(np.median(cpu))


def run_case(name, root, methods, masks, compose, repeat, out):
    from psbench.registry import methods as registered
    from psbench.solve import kernel

    images, lights, omask, truth, label = load_case(name, root)
    rows = []
    for m in masks:
        res, t, c = timed(lambda: ps.solve(images, lights, mask=m, object_mask=omask), repeat)
        rows.append((f"mask {m}" if m != "None" else "None (L2)", "-",
                     ps.normal_error(res.normals, truth, object_mask=omask), t, c, None))
    t_none = rows[0][3] if masks and masks[0] == "None" else None
    specs = registered()
    valids = {"None": np.ones(images.shape, dtype=bool)}
    if compose:
        valids[compose] = ps.solve(images, lights, mask=compose, object_mask=omask).valid
    for vname, valid in valids.items():
        for meth in methods:
            if meth not in specs:
                rows.append((meth, vname, float("nan"), float("nan"), float("nan"),
                             "not registered"))
                continue
            spec = specs[meth]
            opts = spec.options()

            def call():
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    return spec.func(_problem(images, lights, valid, omask), opts)
            try:
                fit, t, c = timed(call, repeat)
            except Exception as exc:  # report and go on
                rows.append((meth, vname, float("nan"), float("nan"), float("nan"),
                             f"{type(exc).__name__}: {exc}"))
                continue
            n, _ = kernel.split(fit.b)
            conv = fit.converged
            note = None
            if np.ndim(conv) and not np.asarray(conv)[omask].all():
                note = f"{(~np.asarray(conv)[omask]).mean():.1%} not converged"
            elif conv is False:
                note = "not converged"
            ne = ps.normal_error(n, truth, object_mask=omask)
            rows.append((meth, vname, ne, t, c, note))
            if vname == "None":
                RESULTS[(name, meth)] = (ne, t, c, FIRST_CALL[-1])
    print(f"\n### {label}: {images.shape[0]} images, {int(omask.sum())} object pixels\n",
          file=out)
    print("| method | valid from | NE (deg) | time (s) | / None | CPU (s) | note |", file=out)
    print("|---|---|---|---|---|---|---|", file=out)
    for meth, vname, ne, t, c, note in rows:
        ratio = f"{t / t_none:.1f}" if t_none and np.isfinite(t) else "-"
        print(f"| {meth} | {vname} | {ne:.2f} | {t:.3f} | {ratio} | {c:.3f} | {note or ''} |",
              file=out)
    out.flush()
    return rows


def th_study(root, out, subsets=("all", "30x8+60x8", "12x4+32x4", "45x4")):
    """Why the thesis's Th fails on real photographs with few lights: per DiLiGenT
    object and light subset, what Eq. 3.2 (bounds k_low / k_up times each image's
    range) marks, how many pixels keep fewer than three observations (Eq. 3.1's
    completion then decides), and NE of None and Th under each ``th_scope``."""
    from psbench.harness.run import select_lights
    from psbench.io import read_dataset
    from psbench.solve.thresholds import resolve_thresholds

    print("\n### Th on real photographs (literal Eq. 3.2)\n", file=out)
    print("| object | lights | k | k_low | k_up | max/p99 (median, max) | Th: shadow | "
          "Th: highlight | Th: pixels < 3 valid | Hi: marked (k_Hi) | CS: marked (k_CS) | "
          "None | Th image | Th object | Th robust | Hi | CS |", file=out)
    print("|---" * 17 + "|", file=out)
    for obj in ("cat", "bear"):
        ds = read_dataset(root / obj)
        for spec in subsets:
            images, lights = ((ds.images, ds.lights) if spec == "all"
                              else select_lights(ds.images, ds.lights, spec))
            k = images.shape[0]
            thr = resolve_thresholds(k, lights, None)
            flat = images.reshape(k, -1)
            rng = flat.max(axis=1) - flat.min(axis=1)
            on = images[:, ds.object_mask]
            spot = flat.max(axis=1) / np.percentile(on, 99, axis=1)
            low = on < thr["k_low"] * rng[:, None]
            up = on > thr["k_up"] * rng[:, None]
            few = ((~(low | up)).sum(axis=0) < 3).mean()
            # Hi / CS (Eqs. 3.9-3.10) on the residuals of the unmasked solution
            b = ps.solve(images, lights, object_mask=ds.object_mask).b[ds.object_mask]
            res = on - (np.asarray(lights.S, dtype=np.float32) @ b.T)
            hi = (res > thr["k_Hi"] * rng[:, None]).mean()
            cs = (res < thr["k_CS"] * rng[:, None]).mean()
            ne = [ps.normal_error(ps.solve(images, lights, object_mask=ds.object_mask).normals,
                                  ds.normals, object_mask=ds.object_mask)]
            for mask, scope in (("Th", "image"), ("Th", "object"), ("Th", "robust"),
                                ("Hi", "image"), ("CS", "image")):
                r = ps.solve(images, lights, mask=mask, object_mask=ds.object_mask, th_scope=scope)
                ne.append(ps.normal_error(r.normals, ds.normals, object_mask=ds.object_mask))
            print(f"| {obj} | {spec} | {k} | {thr['k_low']:.3f} | {thr['k_up']:.2f} | "
                  f"{np.median(spot):.2f}, {spot.max():.2f} | {low.mean():.0%} | {up.mean():.0%} | "
                  f"{few:.0%} | {hi:.0%} ({thr['k_Hi']:.2f}) | {cs:.0%} ({thr['k_CS']:.2f}) | "
                  + " | ".join(f"{v:.2f}" for v in ne) + " |", file=out)
    out.flush()


def acceptance(out):
    """One line per target of the robust methods that this run measured: value,
    target, met or not (times: median wall seconds of the whole call)."""
    print("\n### Acceptance (median wall time of the whole call; NE in degrees)\n", file=out)
    print("| case | method | quantity | measured | target | met | CPU (s) | first call (s) |",
          file=out)
    print("|---|---|---|---|---|---|---|---|", file=out)
    for case, meth, what, lim in TARGETS:
        if (case, meth) not in RESULTS:
            continue
        ne, t, c, first = RESULTS[(case, meth)]
        v = ne if what == "NE" else t
        ok = "yes" if v <= lim else "NO"
        unit = "deg" if what == "NE" else "s"
        print(f"| {case} | {meth} | {what} | {v:.3f} {unit} | <= {lim:g} {unit} | {ok} | "
              f"{c:.3f} | {first:.3f} |", file=out)
    out.flush()


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", help="folder holding diligent/ (default $PSBENCH_DATA or ../shared/data)")
    ap.add_argument("--cases", nargs="*", default=CASES, choices=CASES)
    ap.add_argument("--methods", nargs="*", default=METHODS)
    ap.add_argument("--masks", nargs="*", default=MASKS)
    ap.add_argument("--compose", default=None, help="also run every method on this mask's valid")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--blas-threads", default="1", help="BLAS threads (0: library default)")
    ap.add_argument("--threads", type=int, default=1,
                    help="numba threads (psbench runs pin 1; 0: numba's default); the "
                         "robust methods' kernels are serial, other compiled kernels use it")
    ap.add_argument("--th-study", action="store_true",
                    help="also print what the literal Th does on the DiLiGenT light subsets")
    a = ap.parse_args(argv)
    root = data_root(a.data) / "diligent"
    cases = [c for c in a.cases if c == "sombrero" or root.is_dir()]
    if len(cases) < len(a.cases):
        print(f"DiLiGenT data not found under {root}; real cases skipped", file=sys.stderr)
    import numba

    if a.threads > 0:
        numba.set_num_threads(min(a.threads, numba.config.NUMBA_NUM_THREADS))
    load = os.getloadavg()
    print(f"# psbench robust methods ({time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}), "
          f"median of {a.repeat} after a warm-up call, BLAS threads {a.blas_threads}, numba "
          f"threads {numba.get_num_threads()}, {os.cpu_count()} CPUs, load average "
          f"{load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    for c in cases:
        run_case(c, root, a.methods, a.masks, a.compose, a.repeat, sys.stdout)
    if a.th_study and root.is_dir():
        th_study(root, sys.stdout)
    acceptance(sys.stdout)
    load = os.getloadavg()
    print(f"\nload average at the end: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
