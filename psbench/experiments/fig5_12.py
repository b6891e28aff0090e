"""Fig. 5.12: NE vs noise for the selected masks."""
from __future__ import annotations

from psbench.report.aggregates import long_frame, group_mean, fmt_num, mask_family, series
from psbench.report.verdicts import verdict, nodata, slope, num

TITLE = "Fig. 5.12: NE vs noise for the selected masks"
AVERAGES = ("Mean NE over the five surfaces (the semisphere on its ground plane), 45x8, "
            "TS + shadows; NL is the extended mask"
            " xNL (8 images), NL-Sh is xNL-Sh.")
NOTES = "NL is its extension xNL at 8 images (NL-Sh is xNL-Sh)."
GATED = True
THESIS = {}


def _records(df):
    recs = []
    if df.empty:
        return recs
    d = df.copy()
    d["_fam"] = d["mask"].map(mask_family)
    group_mean(d, ["_fam", "noise"], "ne_mean", recs, lambda k: "", lambda k: k[0],
               lambda k: fmt_num(k[1]))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    fams = ["None", "NL", "Th", "NL-Sh", "Th-Hi-Re-Sh", "RA"]
    s = {f: series(agg, "", f) for f in fams}
    sl = {f: slope(v) for f, v in s.items() if len(v) > 1}
    if not sl:
        return [nodata("NE increases with noise for every mask")]
    out.append(verdict("NE increases with noise for every mask", all(v > 0 for v in sl.values()),
                       ", ".join(f"{k} {v:.1f} deg/unit noise" for k, v in sl.items())))
    if "None" in sl:
        masked = {k: v for k, v in sl.items() if k != "None"}
        out.append(verdict("Masked PS is more noise-sensitive than None (steeper NE vs noise)",
                           all(v > sl["None"] for v in masked.values()),
                           f"None {sl['None']:.1f}; " + ", ".join(f"{k} {v:.1f}"
                                                                  for k, v in masked.items())))
    if "Th" in sl and "NL" in sl:
        out.append(verdict("Th is less noise-sensitive than NL (NL more noise-sensitive)",
                           sl["Th"] < sl["NL"], f"slopes Th {sl['Th']:.1f} vs NL {sl['NL']:.1f}"))
    if "NL" in sl:
        steep = max(sl, key=sl.get)
        rank = ", ".join(f"{k} {v:.1f}" for k, v in sorted(sl.items(), key=lambda kv: -kv[1]))
        out.append(verdict("NL is the most noise-sensitive of the selected masks (steepest NE vs "
                           "noise; the thesis states NL > Th and calls RA very sensitive)",
                           steep == "NL", f"steepest: {steep}; slopes (deg per unit noise): {rank}",
                           undecided=steep != "NL" and sl[steep] - sl["NL"] < 1.0))
    if "RA" in s and "None" in s and len(s["RA"]):
        hi = [n for n in s["RA"].index if n > 0.15 and n in s["None"].index]
        lo = [n for n in s["RA"].index if n <= 0.05 and n in s["None"].index]
        if hi:
            out.append(verdict("RA becomes worse than None above 15 % noise",
                               all(s["RA"][n] > s["None"][n] for n in hi),
                               ", ".join(f"noise {n:g}: RA {num(s['RA'][n])} / None "
                                         f"{num(s['None'][n])}" for n in lo + hi)))
    return out


TABLE_AXES = {"": ("mask", "noise level (% of each image's range)")}


def column_label(part, column):
    try:
        return f"noise {100 * float(column):g} %"
    except ValueError:
        return column


def figures(agg):
    """NE vs noise level per mask family."""
    from psbench.report.figures import finish, line, new_figure, row_names

    fig, (ax,) = new_figure()
    for f in row_names(agg):
        line(ax, agg, "", f, scale=100.0)
    finish(ax, "noise (% of each image's range)", "mean NE (deg)",
           "NE vs noise, 45x8, five surfaces")
    return [("fig5_12", fig)]
