"""The breechface study on a subset (or all) of the shared real scans: its table and costs.

Renders every chosen scan (brass / nickel, frame metering as experiment ``breechface``),
reconstructs it with the chosen method labels and integrators (``recipe``: psbench's
:func:`psbench.forensic.reconstruct_heights`), compares every pair by CMC
(:func:`psbench.forensic.cmc`) and prints the per-method table of
:func:`psbench.forensic.breechface.summarise`, the measured per-scan and per-pair costs
and the full-scale estimate (95 scans, 4,465 pairs per map). Maps and comparisons go to
the study cache (``--cache``, :mod:`psbench.forensic.study_cache`; the experiment's
default folder, so the two share their work): a second run with the same scans and
methods only reads them back, and its times are those of the first.

    nice -n 10 .venv/bin/python benchmarks/breechface_study.py --per-gun 3 --guns 1,2,3 \\
        --methods None,Th-Hi-Re-Sh --finishes brass --jobs 2
"""
import argparse
import os
import time
import warnings

import numpy as np
import pandas as pd

from psbench.forensic import breechface as bf
from psbench.forensic import breechface_runs as br
from psbench.forensic.cmc import CMC_DEFAULTS
from psbench.forensic.identify import bandpass


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--per-gun", type=int, default=3, help="scans per gun (0: all)")
    ap.add_argument("--guns", default="1,2,3", help="comma-separated guns ('' = all)")
    ap.add_argument("--methods", default="None,Th-Hi-Re-Sh,recipe")
    ap.add_argument("--integrators", default="poisson")
    ap.add_argument("--finishes", default="brass")
    ap.add_argument("--meter", default="frame", choices=("frame", "object"))
    ap.add_argument("--cache", default=os.environ.get("PSBENCH_CACHE", "results/cache")
                    + "/breechface", help="study cache folder ('' = none)")
    ap.add_argument("--jobs", type=int, default=1, help="processes for the comparisons")
    ap.add_argument("--out", default=None, help="write scores.csv and summary.csv here")
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    st = br.study_options({"guns": [g for g in args.guns.split(",") if g] or None,
                           "per_gun": args.per_gun or None,
                           "finishes": args.finishes.split(","),
                           "integrators": args.integrators.split(","), "meter": args.meter,
                           "cache": args.cache or None, "jobs": args.jobs})
    print(f"load average {os.getloadavg()}")
    names, heights, valid, guns, px = br.load_scans(st)
    cache = br.StudyCache(st["cache"])
    gun, vm = dict(zip(names, guns)), dict(zip(names, valid))
    print(f"{len(names)} scans of guns {sorted(set(guns))}, {px:g} um pixels")
    scans = {n: bandpass(np.where(v, h, 0.0), v, pixel_size=px, short=CMC_DEFAULTS["short"],
                         long=CMC_DEFAULTS["long"]) for n, h, v in zip(names, heights, valid)}
    frames, per_scan = [], []
    t0 = time.perf_counter()
    frames.append(pd.DataFrame(br.run_scores(scans, vm, gun, px, st, cache, method=bf.SCAN,
                                             integrator="-", finish="-")))
    for finish in st["finishes"]:
        for label in args.methods.split(","):
            maps, rows = br.method_maps(label, names, heights, valid, px, st, seed=0,
                                        finish=finish, cache=cache)
            per_scan += rows
            for integ, mm in maps.items():
                frames.append(pd.DataFrame(br.run_scores(mm, vm, gun, px, st, cache,
                                                         method=label, integrator=integ,
                                                         finish=finish)))
    wall = time.perf_counter() - t0
    scores = pd.concat(frames, ignore_index=True)
    per = pd.DataFrame(per_scan)
    summary = bf.summarise(scores, per)
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        scores.to_csv(os.path.join(args.out, "scores.csv"), index=False)
        summary.to_csv(os.path.join(args.out, "summary.csv"), index=False)
    pd.set_option("display.width", 250)
    cols = ["finish", "method", "integrator", "auc_cmc", "auc_ccf", "separation_cmc",
            "separation_ccf", "fp", "fn", "eer_cmc", "eer_ccf", "same_median_cmc",
            "diff_max_cmc", "height_error_um", "scan_s", "pair_s"]
    print(summary[[c for c in cols if c in summary]].round(3).to_string(index=False))
    pair_s = float(scores.seconds.median())
    scan_s = float(per.groupby(["finish", "method"]).scan_s.median().median()) if len(per) \
        else float("nan")
    n_maps = 2 * len(br.LABELS) * 2 + 1
    print(f"this run: {wall:.0f} s wall ({args.jobs} process(es) for the comparisons; "
          "cached pieces cost nothing)")
    print(f"per scan and label (render, solve, integrate, band-pass): {scan_s:.1f} s; per "
          f"pair: {pair_s:.2f} s (median, one process)")
    print(f"experiment breechface, full scale: 95 scans x {2 * len(br.LABELS)} (finish, label)"
          f" x {scan_s:.1f} s = {95 * 2 * len(br.LABELS) * scan_s / 3600:.1f} h of "
          f"reconstruction + {n_maps} maps x 4465 pairs x {pair_s:.2f} s = "
          f"{4465 * n_maps * pair_s / 3600:.1f} h of comparisons (CPU; divide by the "
          "processes)")
    print(f"load average {os.getloadavg()}")


if __name__ == "__main__":
    main()
