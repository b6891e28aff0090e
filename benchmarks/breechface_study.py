"""The breechface study on a subset (or all) of the shared real scans, with a cache.

Renders every chosen scan (brass / nickel), reconstructs it with the chosen methods and
integrators and psbench's recipe (:func:`psbench.forensic.reconstruct_heights`), caches
the band-passed maps per scan (``OUT/cache/<finish>/<scan>.npz``), compares every pair
by CMC (:func:`psbench.forensic.cmc`) and prints the per-method table of
:func:`psbench.forensic.breechface.summarise`; it also prints the measured per-scan and
per-pair costs and the full-scale estimate (95 scans, 4,465 pairs per recipe).

    nice -n 10 .venv/bin/python benchmarks/breechface_study.py --per-gun 3 --guns 1,2,3 \\
        --methods None,Th-Hi-Re-Sh --finishes brass --out /tmp/bf
"""
import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from psbench.forensic import breechface as bf
from psbench.forensic.recipe import reconstruct_heights
from psbench.forensic.scans import read_guns
from psbench.io import read_x3p


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--per-gun", type=int, default=3)
    ap.add_argument("--guns", default="1,2,3")
    ap.add_argument("--methods", default="None,Th-Hi-Re-Sh")
    ap.add_argument("--integrators", default="poisson")
    ap.add_argument("--finishes", default="brass")
    ap.add_argument("--out", default="/tmp/breechface")
    ap.add_argument("--meter", default="frame", choices=("frame", "object"))
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    table = read_guns()
    guns = args.guns.split(",")
    table = table[table.gun.isin(guns)].groupby("gun").head(args.per_gun)
    gun = dict(zip(table.scan, table.gun))
    methods = tuple(m for m in args.methods.split(",") if m)
    integ = tuple(args.integrators.split(","))
    out = Path(args.out)
    print(f"load average {os.getloadavg()}; {len(table)} scans of guns {guns}")
    frames, per_scan, t_scan = [], [], []
    for finish in args.finishes.split(","):
        maps, valid = {}, {}
        for scan, path in zip(table.scan, table.path):
            cache = out / "cache" / f"{finish}-{args.meter}" / f"{scan}.npz"
            topo = read_x3p(path)
            v = topo.valid & np.isfinite(topo.height)
            valid[scan] = v
            if cache.is_file():
                with np.load(cache, allow_pickle=True) as f:
                    m, rows = f["maps"].item(), list(f["rows"])
            else:
                t0 = time.perf_counter()
                m, rows = bf.reconstruct_scan(topo.height, v, pixel_size=topo.pixel_size,
                                              methods=methods, integrators=integ,
                                              finish=finish, recipe=reconstruct_heights,
                                              meter=args.meter)
                t_scan.append(time.perf_counter() - t0)
                cache.parent.mkdir(parents=True, exist_ok=True)
                tmp = cache.with_suffix(".tmp.npz")
                np.savez(tmp, maps=np.array(m, dtype=object), rows=np.array(rows, dtype=object))
                os.replace(tmp, cache)
            for key, z in m.items():
                maps.setdefault(key, {})[scan] = z
            per_scan += [{**r, "finish": finish, "scan": scan} for r in rows]
            print(f"{finish} {scan} reconstructed", flush=True)
        px = topo.pixel_size
        for (method, integrator), mm in maps.items():
            sc = bf.score_pairs(mm, valid, gun, pixel_size=px)
            sc["finish"], sc["method"], sc["integrator"] = finish, method, integrator
            frames.append(sc)
            print(f"{finish} {method}/{integrator}: {len(sc)} pairs, "
                  f"{sc.seconds.median():.2f} s per pair", flush=True)
    scores = pd.concat(frames, ignore_index=True)
    per = pd.DataFrame(per_scan)
    summary = bf.summarise(scores, per)
    out.mkdir(parents=True, exist_ok=True)
    scores.to_csv(out / "scores.csv", index=False)
    summary.to_csv(out / "summary.csv", index=False)
    pd.set_option("display.width", 250)
    cols = ["finish", "method", "integrator", "auc_cmc", "auc_ccf", "separation_cmc",
            "separation_ccf", "fp", "fn", "eer_cmc", "eer_ccf", "same_median_cmc",
            "diff_max_cmc", "height_error_um", "solve_s", "pair_s"]
    print(summary[[c for c in cols if c in summary]].round(3).to_string(index=False))
    pair_s = float(scores.seconds.median())
    groups = scores.groupby(["finish", "method", "integrator"]).ngroups
    scan_s = float(np.median(t_scan)) if t_scan else float("nan")
    print(f"per scan (all methods): {scan_s:.1f} s; per pair: {pair_s:.2f} s; full scale "
          f"estimate for these {groups} groups: 95 scans x {scan_s:.0f} s + 4465 pairs x "
          f"{groups} x {pair_s:.2f} s = {(95 * scan_s + 4465 * groups * pair_s) / 3600:.1f} h")
    # experiment breechface at scale full: 2 finishes x 7 labels x 2 integrators + scans
    n_maps = 2 * 7 * 2 + 1
    print(f"experiment breechface, full scale (95 scans, 2 finishes, {n_maps} maps of 4465 "
          f"pairs): {2 * 95 * scan_s / 3600:.1f} h of reconstruction (if this run's "
          f"methods are all of them) + {4465 * n_maps * pair_s / 3600:.1f} h of comparisons")
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
