"""Fig. 5.13: NE vs light count for the selected masks."""
from __future__ import annotations

from psbench.report.aggregates import (long_frame, group_mean, fmt_num, n_images,
                                       mask_family, series)
from psbench.report.verdicts import verdict, nodata, lowest, slope, num

TITLE = "Fig. 5.13: NE vs light count for the selected masks"
AVERAGES = ("Mean NE over the five surfaces and noise 0/10/20 %, 45-degree rings; NL / "
            "NL-Sh for 4 images and xNL / xNL-Sh for 6-12 images.")
NOTES = ""
GATED = False
THESIS = {}


def _records(df):
    recs = []
    if df.empty:
        return recs
    d = df.copy()
    d["_fam"] = d["mask"].map(mask_family)
    d["_n"] = n_images(d)
    group_mean(d, ["_fam", "_n"], "ne_mean", recs, lambda k: "", lambda k: k[0],
               lambda k: fmt_num(k[1]))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    s = {f: series(agg, "", f) for f in ("None", "NL", "Th", "NL-Sh", "Th-Hi-Re-Sh", "RA")}
    ra, no = s["RA"], s["None"]
    if len(ra) and len(no):
        n4 = 4.0 in ra.index and 4.0 in no.index and ra[4.0] > no[4.0]
        ge6 = [n for n in ra.index if n >= 6 and n in no.index]
        better6 = all(ra[n] < no[n] for n in ge6) if ge6 else False
        out.append(verdict("RA needs >= 6 images (worse than None at 4, better from 6 on)",
                           n4 and better6,
                           ", ".join(f"n={int(n)}: RA {num(ra[n])} / None {num(no[n])}"
                                     for n in ra.index if n in no.index)))
    else:
        out.append(nodata("RA needs >= 6 images"))
    if len(no) > 1:
        d = no.iloc[0] - no.iloc[-1]
        out.append(verdict("None: NE decreases only slightly from 4 to 12 images", 0 <= d < 2.0,
                           f"{num(no.iloc[0])} -> {num(no.iloc[-1])}"))
    rel = {}
    for f in ("Th", "Th-Hi-Re-Sh", "NL-Sh"):
        m = s[f]
        c = [n for n in m.index if n in no.index]
        if len(c) > 1:
            rel[f] = ((no[c[0]] - m[c[0]]) / no[c[0]], (no[c[-1]] - m[c[-1]]) / no[c[-1]])
    if rel:
        out.append(verdict("The relative improvement of masks over None grows with image count",
                           all(b > a for a, b in rel.values()),
                           ", ".join(f"{k}: {100 * a:.0f} % -> {100 * b:.0f} %"
                                     for k, (a, b) in rel.items())))
    sl = {f: slope(v) for f, v in s.items() if len(v) > 1}
    if "RA" in sl:
        out.append(lowest("RA improves the most with increasing image count (steepest fall)",
                          sl, "RA", margin=0.05, unit="deg/image"))
    return out


TABLE_AXES = {"": ("mask", "")}


def column_label(part, column):
    return f"{column} images"


def figures(agg):
    """NE vs image count per mask family."""
    from psbench.report.figures import finish, line, new_figure, row_names

    fig, (ax,) = new_figure()
    for f in row_names(agg):
        line(ax, agg, "", f)
    finish(ax, "image count n_i (45-degree ring)", "mean NE (deg)",
           "NE vs image count, five surfaces, noise 0/10/20 %")
    return [("fig5_13", fig)]
