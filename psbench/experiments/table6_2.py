"""Table 6.2: time of WPS relative to 2Z PS on real image folders."""
from __future__ import annotations

import numpy as np

from psbench.report.aggregates import long_frame, labels, data_name, weight_row
from psbench.report.verdicts import verdict, nodata, part_values, num

TITLE = "Table 6.2: time of WPS relative to 2Z PS"
AVERAGES = ("Median t_solve of each WPS weight divided by the median t_solve of 2Z PS on"
            " the same layout and folder, then averaged over folders.")
NOTES = "Times on a shared 2-core machine (three repeats, medians); see table6_1."
GATED = False

# Elapsed time normalized w.r.t. 2Z PS.
THESIS = {"": {
    "None": {"30x4+60x4": 1.00, "30x8+60x8": 1.00},
    "e": {"30x4+60x4": 2.89, "30x8+60x8": 2.65},
    "eZsource": {"30x4+60x4": 2.91, "30x8+60x8": 2.62},
    "eZsurface": {"30x4+60x4": 3.06, "30x8+60x8": 2.68},
    "eZsourceZsurface": {"30x4+60x4": 3.06, "30x8+60x8": 2.69},
}}


def cell_kind(part, column):
    return "ratio"


TABLE_AXES = {"": ("WPS weight (None = 2Z PS)", "light layout")}


def cell_unit(part, column):
    return "x 2Z PS"


def _records(df):
    recs = []
    if df.empty:
        return recs
    d = df.copy()
    d["_row"] = labels(d, weight_row)
    d["_obj"] = [data_name(x) for x in d.get("data", [None] * len(d))]
    tcol = "t_solve"
    for lay, g in d.groupby("lights"):
        base = g[g["_row"] == "None"].groupby("_obj")[tcol].median()
        for w, gw in g.groupby("_row"):
            m = gw.groupby("_obj")[tcol].median()
            ratios = [m[o] / base[o] for o in m.index if o in base.index and base[o] > 0]
            if ratios:
                recs.append(("", w, str(lay), float(np.mean(ratios)), int(len(gw))))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    if agg is None or agg.empty:
        return [nodata("WPS costs about 3x PS")]
    out = []
    for lay in sorted(agg["column"].unique()):
        r = {k: v for k, v in part_values(agg, "", lay).items() if k != "None"}
        if r:
            m = float(np.mean(list(r.values())))
            out.append(verdict(f"WPS costs about 3x PS (2-4x; {lay})", 2.0 <= m <= 4.0,
                               ", ".join(f"{k} {num(v)}x" for k, v in r.items())
                               + f"; mean {num(m)}x (thesis 2.6-3.1x)"))
    return out or [nodata("WPS costs about 3x PS")]


def prepare(root, scale):
    """Make the simulated-rig captures the grid reads, under ``<root>/simrig``, when they
    are missing (deterministic; see :mod:`psbench.experiments._simrig`)."""
    from ._simrig import prepare as make

    make(root, scale)
