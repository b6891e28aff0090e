"""Fig. 4.6: intensity error (IE) decomposition vs source zenith."""
from __future__ import annotations

import numpy as np

from psbench.report.aggregates import long_frame, fmt_num, ie_components, series
from psbench.report.verdicts import verdict, nodata

TITLE = "Fig. 4.6: IE decomposition vs source zenith"
AVERAGES = ("Per sombrero, 8 lights, TS + shadows, no noise: the highlight, shadow and "
            "total intensity error of the rendered images w.r.t. the Lambert model "
            "(psbench.analysis.ie_decomposition payload).")
NOTES = ""
GATED = False
THESIS = {}


def cell_kind(part, column):
    return "ie"


def _records(df):
    recs = []
    if df.empty:
        return recs
    for (s, z), g in df.groupby(["surface", "zenith"]):
        comps = [ie_components(p) for p in g.get("payload", [])]
        for comp in ("highlight", "shadow", "self_shadow", "cast_shadow", "total"):
            vals = [c[comp] for c in comps if comp in c]
            if vals:
                recs.append((str(s), comp, fmt_num(z), float(np.mean(vals)), len(vals)))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    if agg is None or agg.empty:
        return [nodata("Highlight IE falls and shadow IE rises with Z_source")]
    hv, sv = [], []
    for s in sorted(agg["part"].unique()):
        h, sh = series(agg, s, "highlight"), series(agg, s, "shadow")
        if len(h) > 1:
            hv.append(h.iloc[-1] < h.iloc[0])
        if len(sh) > 1:
            sv.append(sh.iloc[-1] > sh.iloc[0])
    out.append(verdict("Highlight IE falls with Z_source on every sombrero",
                       all(hv) if hv else None, f"{sum(hv)}/{len(hv)} sombreros"))
    out.append(verdict("Shadow IE rises with Z_source on every sombrero", all(sv) if sv else None,
                       f"{sum(sv)}/{len(sv)} sombreros"))
    return out


TABLE_AXES = {"*": ("IE component", "source zenith (deg)")}


def figures(agg):
    """IE components vs source zenith, one panel per sombrero."""
    from psbench.report.figures import figure_legend, finish, line, new_figure

    fig, axes = new_figure(ncols=3, w=4.6, h=4.8)
    for ax, s in zip(axes, ("sombrero1", "sombrero2", "sombrero3")):
        for comp in ("highlight", "shadow", "total"):
            line(ax, agg, s, comp)
        finish(ax, "source zenith (deg)", "IE (% of image range)", s, legend=False)
    figure_legend(fig)
    return [("fig4_6", fig)]
