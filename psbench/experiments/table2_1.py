"""Table 2.1: condition value cond(S) of single-ring light layouts (no images)."""
from __future__ import annotations

import numpy as np
import pandas as pd

from psbench.report.aggregates import (fmt_num, group_mean, long_frame, n_images,
                                       parse_json, series)
from psbench.report.verdicts import nodata, ok, verdict

TITLE = "Table 2.1: condition value of single-ring layouts"
AVERAGES = ("cond(S) = sigma_max / sigma_min of the (k,3) light matrix of a single ring "
            "(kind=cond runs; no images).")
NOTES = ""
GATED = True

# Lines ~400-427: condition value of S for n lights (row) at zenith z (column).
THESIS = {"": {
    "4": {"5": 16.1645, "15": 5.2779, "30": 2.4495, "45": 1.4142, "60": 1.2247},
    "8": {"5": 16.1645, "15": 5.2779, "30": 2.4495, "45": 1.4142, "60": 1.2247},
}}


def cell_kind(part, column):
    return "cond"


TABLE_AXES = {"": ("lights", "source zenith of the ring (deg)")}


def aggregate(rows):
    """Mean cond(S) per image count (row) and zenith (column)."""
    recs = []
    d = rows.copy()
    d["_n"] = n_images(d)
    val = d["cond"] if "cond" in d and d["cond"].notna().any() else \
        pd.Series([(parse_json(p) or {}).get("cond") if isinstance(parse_json(p), dict) else None
                   for p in d.get("payload", [None] * len(d))], index=d.index)
    d["_cond"] = pd.to_numeric(val, errors="coerce")
    group_mean(d, ["_n", "zenith"], "_cond", recs, lambda k: "",
               lambda k: fmt_num(k[0]), lambda k: fmt_num(k[1]))
    return long_frame(recs)


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    c4, c8 = series(agg, "", "4"), series(agg, "", "8")
    if c4.empty or c8.empty:
        return [nodata("The number of light sources does not change the condition value"),
                nodata("Larger zenith angles have a better (smaller) condition value")]
    common = c4.index.intersection(c8.index)
    dmax = float(np.max(np.abs(c4[common] - c8[common]))) if len(common) else float("nan")
    out.append(verdict("The number of light sources does not change the condition value",
                       dmax < 1e-3 if ok(dmax) else None,
                       f"max |cond(4 lights) - cond(8 lights)| = {dmax:.2e} over zeniths "
                       f"{', '.join(fmt_num(z) for z in common)}"))
    mono = all(bool((np.diff(s.to_numpy()) < 0).all()) for s in (c4, c8))
    out.append(verdict("Larger zenith angles have a better (smaller) condition value",
                       bool(mono), "4 lights: " + ", ".join(f"{fmt_num(z)}deg {v:.4f}"
                                                            for z, v in c4.items())))
    th = THESIS[""]
    errs = [abs(float(v) - th[n][fmt_num(z)]) for n, s in (("4", c4), ("8", c8))
            for z, v in s.items() if fmt_num(z) in th[n]]
    if errs:
        out.append(verdict("psbench reproduces every printed condition value (to 1e-3)",
                           max(errs) < 1e-3, f"max |psbench - thesis| = {max(errs):.2e} over "
                           f"{len(errs)} cells"))
    return out
