"""Table 5.6: binary vs weighted fusion of WPS."""
from __future__ import annotations

import numpy as np

from psbench.report.aggregates import long_frame, mean, lookup
from psbench.report.verdicts import NE_MARGIN, verdict, nodata, ok, num

TITLE = "Table 5.6: binary vs weighted WPS"
AVERAGES = ("NE per sombrero (and their mean) of WPS eZsourceZsurface on 30x8+60x8, TS +"
            " shadows, 5 % noise, weighted vs binary fusion.")
NOTES = ""
GATED = True

# Angular NE, 30x8+60x8, WPS eZsourceZsurface, weighted vs binary fusion.
THESIS = {"": {
    "weighted": {"sombrero1": 4.08, "sombrero2": 6.12, "sombrero3": 6.74, "mean": 5.65},
    "binary": {"sombrero1": 3.39, "sombrero2": 5.19, "sombrero3": 7.00, "mean": 5.19},
}}


TABLE_AXES = {"": ("fusion of the two rings", "surface")}


def _records(df):
    recs = []
    if df.empty:
        return recs
    for binary, g in df.groupby("binary"):
        row = "binary" if bool(binary) else "weighted"
        per = []
        for s, gs in g.groupby("surface"):
            v, n = mean(gs["ne_mean"])
            if n:
                recs.append(("", row, str(s), v, n))
                per.append(v)
        if per:
            recs.append(("", row, "mean", float(np.mean(per)), len(per)))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    w, b = lookup(agg, "", "weighted", "mean"), lookup(agg, "", "binary", "mean")
    if not (ok(w) and ok(b)):
        return [nodata("Binary beats weighted fusion on NE (mean of the sombreros)")]
    out = [verdict("Binary beats weighted fusion on NE (mean of the sombreros)", b < w,
                   f"binary {num(b)} vs weighted {num(w)} (thesis 5.19 vs 5.65)",
                   undecided=abs(b - w) < NE_MARGIN)]
    w3, b3 = lookup(agg, "", "weighted", "sombrero3"), lookup(agg, "", "binary", "sombrero3")
    if ok(w3) and ok(b3):
        out.append(verdict("...except on the roughest sombrero3, where weighted is better",
                           w3 < b3, f"sombrero3: weighted {num(w3)} vs binary {num(b3)} "
                           f"(thesis 6.74 vs 7.00)", undecided=abs(w3 - b3) < NE_MARGIN))
    return out
