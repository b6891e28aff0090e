"""Fig. 4.3: NE vs image count for diffuse (Di) and Hi-Sh images."""
from __future__ import annotations

from psbench.report.aggregates import (long_frame, group_mean, fmt_num, model_label, labels,
                                       n_images, series)
from psbench.report.verdicts import verdict, nodata, num

TITLE = "Fig. 4.3: NE vs image count (Di, Hi-Sh)"
AVERAGES = ("Mean NE over sombrero1-3, 45-degree ring of n lights, 5 % noise; Di = "
            "unclamped Lambert (no highlight, no shadow), Hi-Sh = TS with shadows.")
NOTES = ""
GATED = False

# NE values quoted in the text (16 and 32 images).
THESIS = {"": {"Di": {"16": 1.44, "32": 1.38}, "Hi-Sh": {"16": 9.34, "32": 9.25}}}


def _records(df):
    recs = []
    if df.empty:
        return recs
    d = df.copy()
    d["_n"] = n_images(d)
    d["_lab"] = labels(d, model_label)
    group_mean(d, ["_lab", "_n"], "ne_mean", recs, lambda k: "", lambda k: k[0],
               lambda k: fmt_num(k[1]))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    for lab, lim, th in (("Di", 5.0, "1.44 -> 1.38, 4 %"), ("Hi-Sh", 2.0, "9.34 -> 9.25, 1 %")):
        s = series(agg, "", lab)
        if 16 in s.index and 32 in s.index:
            d = 100 * (s[16] - s[32]) / s[16]
            out.append(verdict(f"NE saturates with n_i: 16 -> 32 images changes {lab} NE by "
                               f"< {lim:g} %", d < lim,
                               f"{num(s[16])} -> {num(s[32])} ({num(d, 1)} %; thesis {th})"))
        else:
            out.append(nodata(f"NE saturates with n_i ({lab})"))
    return out


TABLE_AXES = {"": ("images (Di: diffuse; Hi-Sh: highlights + shadows)", "")}


def column_label(part, column):
    return f"{column} images"


def figures(agg):
    """NE vs image count, Di and Hi-Sh, with the two values the thesis quotes."""
    from psbench.report.figures import finish, line, new_figure, thesis

    fig, (ax,) = new_figure()
    for lab in ("Di", "Hi-Sh"):
        line(ax, agg, "", lab, label=f"psbench {lab}")
    xs = [int(k) for lab in ("Di", "Hi-Sh") for k in THESIS[""][lab]]
    ys = [v for lab in ("Di", "Hi-Sh") for v in THESIS[""][lab].values()]
    thesis(ax, xs, ys, label="thesis (quoted in the text)")
    finish(ax, "image count n_i (45-degree ring)", "mean NE (deg)",
           "NE vs image count, 5 % noise", loc="center right")
    return [("fig4_3", fig)]
