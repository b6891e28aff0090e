"""Fig. 4.9: NE vs surface zenith on sombrero2."""
from __future__ import annotations

import numpy as np

from psbench.report.aggregates import long_frame, fmt_num, series_xy, series
from psbench.report.verdicts import verdict, nodata, num

TITLE = "Fig. 4.9: NE vs surface zenith (sombrero2)"
AVERAGES = ("NE binned by surface zenith on sombrero2, 8 lights, TS + shadows, 5 % noise"
            " (ne_by_zenith extra of the solve rows).")
NOTES = ""
GATED = False

# Value quoted in the text: the largest surface zenith of sombrero2.
THESIS = {"quoted": {"max_surface_zenith": {"sombrero2": 66.0}}}


def _records(df):
    recs = []
    if df.empty:
        return recs
    for z, g in df.groupby("zenith"):
        for p in g.get("ne_by_zenith", []):
            xy = series_xy(p)
            if xy is None:
                continue
            for x, y in zip(*xy):
                if np.isfinite(y):
                    recs.append(("", fmt_num(z), f"{x:.4g}", float(y), 1))
            break
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    s30, s60 = series(agg, "", "30"), series(agg, "", "60")
    out = []
    if len(s30) > 2:
        peak = float(s30.idxmax())
        out.append(verdict("At Z_source = 30 deg, NE concentrates at low Z_surface (highlights, "
                           "around Z_source/2)", peak <= 35,
                           f"NE peak at Z_surface {num(peak, 0)} deg"))
    else:
        out.append(nodata("At Z_source = 30 deg, NE concentrates at low Z_surface"))
    if len(s60) > 2:
        x = np.asarray(s60.index, float)
        slope = float(np.polyfit(x, s60.to_numpy(), 1)[0])
        out.append(verdict("At Z_source = 60 deg, NE increases with Z_surface", slope > 0,
                           f"linear slope {slope:.3f} deg/deg"))
    else:
        out.append(nodata("At Z_source = 60 deg, NE increases with Z_surface"))
    return out


TABLE_AXES = {"": ("source zenith (deg)", "surface zenith, bin centre (deg)"),
              "quoted": ("quoted value", "")}
PART_TITLES = {"": "NE (deg) per source zenith and surface zenith",
               "quoted": "Value quoted in the thesis's text"}


def figures(agg):
    """NE vs surface zenith per source zenith; the largest surface zenith of sombrero2
    the thesis quotes as a dashed line."""
    from psbench.report.figures import finish, line, new_figure, row_names

    fig, (ax,) = new_figure()
    for z in sorted(row_names(agg), key=float):
        line(ax, agg, "", z, label=f"Z_source {z} deg")
    ax.axvline(THESIS["quoted"]["max_surface_zenith"]["sombrero2"], color="k", ls="--", lw=1.5,
               label="thesis: largest surface zenith, 66 deg")
    finish(ax, "surface zenith (deg)", "mean NE (deg)", "sombrero2, 8 lights, 5 % noise")
    return [("fig4_9", fig)]
