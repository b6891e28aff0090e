"""The defaults of ``robust`` and ``tsfit`` on the whole stress grid plus DiLiGenT cat and bear.

Cells: every cell of the ``stress`` experiment at the full scale (its 19 departures x 7
surfaces x lights {30x8+60x8, 20x32+40x32+60x32} x noise {0, 2, 5 %}, 64^2, seed 0:
798 cells), expanded from ``psbench/experiments/stress.yaml`` by the harness
(:func:`psbench.harness.grid.expand`) and rendered and solved by the harness's own run
code (``_Scene``, ``solve_run``: the experiment's scenes, bit for bit); and DiLiGenT
``cat`` and ``bear`` with all 96 lights, the 16 lights nearest ``30x8+60x8`` and the 8
nearest ``12x4+32x4`` (the harness's ``lights=`` selection, as ``benchmarks/robust.py``
picks them). On every cell: least squares and ``trim`` (the references) and each
candidate setting below (method options through the run parameter ``options``).
One setting for every object, never one per object.

The rule, fixed before any result was looked at, applied to each method on its own:

* criterion = mean of [mean NE over cat and bear, all six light subsets] and [mean NE
  over all 798 stress cells];
* reported beside it: the number of stress cells where the setting is more than 0.3 deg
  worse than the better of least squares and ``trim`` in that cell, and its mean solve
  time (stress cells; cat and bear);
* the current default stays unless a candidate lowers the criterion by more than
  0.05 deg without increasing that count; if several do, the lowest criterion wins.

Per-cell rows go to ``--out`` (CSV, resumable: cells already there are skipped); the
table and the decision are printed at the end (``--table`` prints them from ``--out``
alone). Runs with 2 joblib workers, one thread each (as the harness runs).

Usage::

    nice -n 10 python benchmarks/defaults_study.py [--out /tmp/defaults_study.csv]
        [--data DIR] [--jobs 2] [--limit N] [--table]
"""
from __future__ import annotations

import argparse
import os
import time
import warnings
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: (label, method, options); the first of each method is its current default
SETTINGS = (
    ("LS", "ps", {}),
    ("trim", "trim", {}),
    ("robust", "robust", {}),
    ("robust c=1.5", "robust", {"c": 1.5}),
    ("robust c=2.0", "robust", {"c": 2.0}),
    ("robust c=3.5", "robust", {"c": 3.5}),
    ("robust model=lambert", "robust", {"model": "lambert"}),
    ("tsfit", "tsfit", {}),
    ("tsfit start=trim", "tsfit", {"start": "trim"}),
    ("tsfit rho_s_mode=pixel", "tsfit", {"rho_s_mode": "pixel"}),
)
#: DiLiGenT light subsets: all lights, and the nearest to these layouts
SUBSETS = (None, "30x8+60x8", "12x4+32x4")
OBJECTS = ("cat", "bear")
#: degrees: a cell counts against a setting when it is this much worse than the better
#: of least squares and trim there
TOLERANCE = 0.3
#: degrees: the criterion must drop by more than this for a default to change
GAIN = 0.05


def cells(data):
    """(name, kind, params of the cell's robust run): real cases first, then stress."""
    from psbench.harness.grid import expand
    from psbench.harness.params import normalize
    from psbench.experiments.stress import departure

    out = []
    for obj in OBJECTS:
        for sub in SUBSETS:
            p = normalize(dict(data=str(Path(data) / obj), lights=sub, method="robust",
                               mask=None))
            out.append((f"{obj} | {sub or 'all 96'}", "real", p))
    for p in expand("stress", "full"):
        if p["method"] == "robust":
            out.append((f"{departure(p)} | {p['surface']} | {p['lights']} | {p['noise']:g}",
                        "stress", p))
    return out


_WARM = set()


def solve_cell(name, kind, p):
    """NE (mean over the object) and solve time of every setting on one cell."""
    import numpy as np
    from psbench.harness._timing import pinned_threads, warm_up
    from psbench.harness.params import normalize
    from psbench.harness.run import _Scene, solve_run
    from psbench.metrics.errors import normal_error_stats

    warnings.simplefilter("ignore")
    rows = []
    with pinned_threads():
        sc = _Scene(p)
        for label, method, opts in SETTINGS:
            q = normalize({**p, "method": method, "mask": None})
            # set after normalize: robust's ``model`` shares its name with the render's
            # run parameter, which normalize refuses in ``options``; solve_run passes them on
            q["options"] = dict(opts)
            if label not in _WARM:         # first call in this process compiles
                warm_up(solve_run, q, sc)
                _WARM.add(label)
            t0 = time.perf_counter()
            res = solve_run(q, sc.images, sc.lights, sc.object_mask)
            t = time.perf_counter() - t0
            ne = normal_error_stats(res.normals, sc.normals, object_mask=sc.object_mask)["mean"]
            fb = getattr(res, "fallback", None)
            rows.append(dict(cell=name, kind=kind, setting=label, ne=ne, t_solve=t,
                             n_images=int(sc.images.shape[0]),
                             fallback=float(np.asarray(fb)[sc.object_mask].mean())
                             if fb is not None else np.nan))
    return rows


def table(d):
    """The rule's table per setting, and the decision per method."""
    import numpy as np
    import pandas as pd

    piv = d.pivot_table(index="cell", columns="setting", values="ne")
    kind = d.groupby("cell")["kind"].first()
    tm = d.pivot_table(index="cell", columns="setting", values="t_solve")
    st, re = kind.index[kind == "stress"], kind.index[kind == "real"]
    best = np.minimum(piv.loc[st, "LS"], piv.loc[st, "trim"])
    rows = []
    for label, method, _ in SETTINGS:
        if label not in piv:
            continue
        real, stress = piv.loc[re, label].mean(), piv.loc[st, label].mean()
        rows.append(dict(setting=label, method=method, criterion=(real + stress) / 2,
                         real=real, stress=stress,
                         worse=int((piv.loc[st, label] > best + TOLERANCE).sum()),
                         t_stress=tm.loc[st, label].mean(), t_real=tm.loc[re, label].mean(),
                         n_real=int(piv.loc[re, label].notna().sum()),
                         n_stress=int(piv.loc[st, label].notna().sum())))
    t = pd.DataFrame(rows)
    print(f"\n{len(st)} stress cells, {len(re)} real cases; worse = stress cells more than "
          f"{TOLERANCE} deg worse than the better of LS and trim; times: mean t_solve (s)\n")
    print("| setting | criterion | real | stress | worse | t stress (s) | t real (s) |")
    print("|---|---|---|---|---|---|---|")
    for r in t.itertuples():
        print(f"| {r.setting} | {r.criterion:.3f} | {r.real:.3f} | {r.stress:.3f} | {r.worse} "
              f"| {r.t_stress:.3f} | {r.t_real:.2f} |")
    for method in ("robust", "tsfit"):
        g = t[t["method"] == method].reset_index(drop=True)
        if g.empty:
            continue
        cur = g.iloc[0]
        ok = g.iloc[1:][(g["criterion"].iloc[1:] < cur["criterion"] - GAIN)
                        & (g["worse"].iloc[1:] <= cur["worse"])]
        win = cur if ok.empty else ok.loc[ok["criterion"].idxmin()]
        print(f"{method}: {'the default stays' if ok.empty else 'new default'}: "
              f"{win['setting']} (criterion {win['criterion']:.3f} against the default's "
              f"{cur['criterion']:.3f})")
    # cells where every setting (and both references) is far off
    worst = piv.loc[st].min(axis=1).sort_values(ascending=False).head(10)
    print("\nstress cells with the highest best-of-all-settings NE:")
    for c, v in worst.items():
        print(f"  {v:6.2f}  {c}")
    return t


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="/tmp/defaults_study.csv")
    ap.add_argument("--data", default=os.environ.get("PSBENCH_DATA", str(ROOT / "../shared/data"))
                    + "/diligent")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--limit", type=int, default=0, help="first N cells only")
    ap.add_argument("--table", action="store_true", help="print the table from --out only")
    a = ap.parse_args(argv)
    import pandas as pd

    if not a.table:
        from joblib import Parallel, delayed

        have = set(pd.read_csv(a.out)["cell"]) if os.path.exists(a.out) else set()
        todo = [c for c in cells(a.data)[:a.limit or None] if c[0] not in have]
        print(f"{len(todo)} cells to solve ({len(have)} done), {len(SETTINGS)} settings, "
              f"{a.jobs} workers", flush=True)
        t0, n = time.perf_counter(), 0
        par = Parallel(n_jobs=a.jobs, return_as="generator_unordered")
        for rows in par(delayed(solve_cell)(*c) for c in todo):
            n += 1
            pd.DataFrame(rows).to_csv(a.out, mode="a", index=False,
                                      header=not os.path.exists(a.out))
            ne = {r["setting"]: r["ne"] for r in rows}
            el = time.perf_counter() - t0
            print(f"[{n}/{len(todo)} {el:5.0f}s eta {el / n * (len(todo) - n):5.0f}s load "
                  f"{os.getloadavg()[0]:.1f}] {rows[0]['cell'][:60]:60s} LS {ne['LS']:6.2f} "
                  f"trim {ne['trim']:6.2f} robust {ne['robust']:6.2f} tsfit {ne['tsfit']:6.2f}",
                  flush=True)
    table(pd.read_csv(a.out))


if __name__ == "__main__":
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS",
                "NUMBA_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    main()
