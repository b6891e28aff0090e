"""Fig. 4.4: NE vs source zenith for diffuse images."""
from __future__ import annotations

from psbench.report.aggregates import long_frame, group_mean, fmt_num, n_images, series
from psbench.report.verdicts import verdict, nodata, num

TITLE = "Fig. 4.4: NE vs source zenith, diffuse images"
AVERAGES = ("Mean NE over sombrero1-3, Lambert without shadows, 5 % noise, per ring size"
            " n and source zenith.")
NOTES = ""
GATED = False

# Value quoted in the text: the optimal source zenith.
THESIS = {"quoted": {"optimum_zenith": {"all": 45.0}}}


def _records(df):
    recs = []
    if df.empty:
        return recs
    d = df.copy()
    d["_n"] = n_images(d)
    group_mean(d, ["_n", "zenith"], "ne_mean", recs, lambda k: "", lambda k: fmt_num(k[0]),
               lambda k: fmt_num(k[1]))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    if agg is None or agg.empty:
        return [nodata("Z_source = 45 deg is optimal for diffuse images at every n_i")]
    opts = {}
    for n in sorted(agg["row"].unique(), key=float):
        s = series(agg, "", n)
        if len(s):
            opts[n] = float(s.idxmin())
    ok = all(40 <= z <= 50 for z in opts.values())
    return [verdict("Z_source = 45 deg is optimal for diffuse images at every n_i (40-50 deg)", ok,
                    ", ".join(f"n={k}: {num(v, 0)} deg" for k, v in opts.items()))]


TABLE_AXES = {"": ("images", "source zenith (deg)"), "quoted": ("quoted value", "")}
PART_TITLES = {"": "NE (deg) per image count and source zenith",
               "quoted": "Value quoted in the thesis's text"}


def column_label(part, column):
    return "all image counts" if column == "all" else column


def figures(agg):
    """NE vs source zenith per image count; the thesis's optimum as a dashed line."""
    from psbench.report.figures import finish, line, new_figure, row_names

    fig, (ax,) = new_figure()
    for n in sorted(row_names(agg), key=float):
        line(ax, agg, "", n, label=f"{n} images")
    ax.axvline(THESIS["quoted"]["optimum_zenith"]["all"], color="k", ls="--", lw=1.5,
               label="thesis: optimum at 45 deg")
    finish(ax, "source zenith (deg)", "mean NE (deg)", "Diffuse images, 5 % noise")
    return [("fig4_4", fig)]
