"""Fig. 5.14: the NL mask vs light count at several noise levels."""
from __future__ import annotations

from psbench.report.aggregates import long_frame, group_mean, fmt_num, n_images, series
from psbench.report.verdicts import NE_MARGIN, verdict, nodata, num

TITLE = "Fig. 5.14: NL mask vs light count at several noise levels"
AVERAGES = ("Mean NE over the five surfaces of NL (4 images) / xNL (6-12 images) per "
            "noise level.")
NOTES = ""
GATED = False
THESIS = {}


def _records(df):
    recs = []
    if df.empty:
        return recs
    d = df.copy()
    d["_n"] = n_images(d)
    group_mean(d, ["noise", "_n"], "ne_mean", recs, lambda k: "", lambda k: fmt_num(k[0]),
               lambda k: fmt_num(k[1]))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    s0 = series(agg, "", "0")
    for nz in ("0.05", "0.1"):
        s = series(agg, "", nz)
        if 8.0 in s.index and 12.0 in s.index:
            out.append(verdict(f"With {float(nz) * 100:g} % noise NL with 12 images is worse than "
                               f"with 8", s[12.0] > s[8.0],
                               f"8 img {num(s[8.0])}, 12 img {num(s[12.0])}",
                               undecided=abs(s[12.0] - s[8.0]) < NE_MARGIN))
        else:
            out.append(nodata(f"With {float(nz) * 100:g} % noise NL with 12 images is worse "
                              f"than with 8"))
    if 8.0 in s0.index and 12.0 in s0.index:
        out.append(verdict("Without noise NL works with 12 images (no worse than 8)",
                           s0[12.0] <= s0[8.0] + NE_MARGIN, f"8 img {num(s0[8.0])}, 12 img "
                           f"{num(s0[12.0])}"))
    return out


TABLE_AXES = {"": ("noise (fraction of each image's range)", "")}


def column_label(part, column):
    return f"{column} images"


def figures(agg):
    """NE of NL / xNL vs image count per noise level."""
    from psbench.report.figures import finish, line, new_figure, row_names

    fig, (ax,) = new_figure()
    for nz in sorted(row_names(agg), key=float):
        line(ax, agg, "", nz, label=f"noise {float(nz) * 100:g} %")
    finish(ax, "image count n_i (45-degree ring)", "mean NE (deg)",
           "NL (4 images) / xNL (6-12 images), five surfaces")
    return [("fig5_14", fig)]
