"""Fig. 4.10: IE vs surface zenith on sombrero2."""
from __future__ import annotations

import numpy as np

from psbench.report.aggregates import long_frame, fmt_num, ie_components, series
from psbench.report.verdicts import verdict, nodata, num

TITLE = "Fig. 4.10: IE vs surface zenith (sombrero2)"
AVERAGES = ("IE binned by surface zenith on sombrero2, 8 lights, TS + shadows "
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
    for z, g in df.groupby("zenith"):
        for p in g.get("payload", []):
            comps = ie_components(p)
            for comp in ("highlight", "shadow", "total"):
                xy = comps.get(comp + "_by_zenith")
                if xy is None:
                    continue
                for x, y in zip(*xy):
                    if np.isfinite(y):
                        recs.append((fmt_num(z), comp, f"{x:.4g}", float(y), 1))
            break
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    if agg is None or agg.empty:
        return [nodata("Highlight IE peaks near Z_surface = Z_source/2")]
    for z in sorted(agg["part"].unique(), key=float):
        h = series(agg, z, "highlight")
        if len(h) > 2:
            peak = float(h.idxmax())
            out.append(verdict(f"Z_source {z}: highlight IE peaks near Z_surface = Z_source/2 "
                               f"(+-10 deg)", abs(peak - float(z) / 2) <= 10,
                               f"peak at {num(peak, 0)} deg, Z_source/2 = {num(float(z) / 2, 1)}"))
        sh = series(agg, z, "shadow")
        lim = 90.0 - float(z)
        below, above = sh[sh.index < lim], sh[sh.index >= lim]
        if len(below) and len(above):
            out.append(verdict(f"Z_source {z}: shadow IE rises beyond Z_surface = 90 - Z_source",
                               float(above.mean()) > float(below.mean()),
                               f"mean shadow IE {num(float(below.mean()))} below {num(lim, 0)} "
                               f"deg vs {num(float(above.mean()))} above"))
    return out or [nodata("Highlight IE peaks near Z_surface = Z_source/2")]


TABLE_AXES = {"*": ("IE component", "surface zenith, bin centre (deg)")}
PART_TITLES = {z: f"Z_source = {z} deg" for z in ("30", "45", "60")}


def figures(agg):
    """IE components vs surface zenith, one panel per source zenith, with Z/2 and 90-Z."""
    from psbench.report.figures import figure_legend, finish, line, new_figure

    if agg is None or agg.empty:
        return []
    parts = sorted(agg["part"].unique(), key=float)
    fig, axes = new_figure(ncols=max(1, len(parts)), w=4.6, h=4.8)
    for ax, z in zip(axes, parts):
        for comp in ("highlight", "shadow", "total"):
            line(ax, agg, z, comp)
        ax.axvline(float(z) / 2, color="k", ls=":", lw=1.5, label="Z_source / 2")
        ax.axvline(90 - float(z), color="k", ls="--", lw=1.5, label="90 - Z_source")
        finish(ax, "surface zenith (deg)", "IE (% of image range)", f"Z_source = {z} deg",
               legend=False)
    figure_legend(fig, ncol=5)
    return [("fig4_10", fig)]
