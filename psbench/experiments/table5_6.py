"""Table 5.6: binary vs weighted fusion of WPS."""
from __future__ import annotations

import numpy as np

from psbench.report.aggregates import long_frame, mean, lookup
from psbench.report.verdicts import by_seed, decide, nodata, num, ok, quoted

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


Q_BINARY = ("line 1370: \"Binary weights that simply selects the less error normal, "
            "performed better than the weighted summation of normal vectors if only normal "
            "error is considered.\" (Table 5.6: binary better on s1 and s2, weighted on s3)")


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment (decided with
    the thesis's own gaps and the seed-to-seed spread of the grid's seeds)."""
    per = by_seed(rows, aggregate)

    def claim_gap(a, col, win, lose):
        return lookup(a, "", lose, col) - lookup(a, "", win, col)

    out = []
    specs = [("Binary beats weighted fusion on NE (mean of the sombreros)", "mean", "binary",
              "weighted"),
             ("...except on the roughest sombrero3, where weighted is better", "sombrero3",
              "weighted", "binary")]
    for claim, col, win, lose in specs:
        g = claim_gap(agg, col, win, lose)
        if not ok(g):
            out.append(quoted(nodata(claim), Q_BINARY))
            continue
        th = THESIS[""][lose][col] - THESIS[""][win][col]
        out.append(quoted(decide(claim, g, f"{col}: {win} {num(lookup(agg, '', win, col))} vs "
                                 f"{lose} {num(lookup(agg, '', lose, col))} (thesis "
                                 f"{THESIS[''][win][col]} vs {THESIS[''][lose][col]})",
                                 thesis_gap=th,
                                 seed_gaps=[claim_gap(a, col, win, lose) for a in per.values()]
                                 or None), Q_BINARY))
    return out
