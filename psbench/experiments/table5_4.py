"""Table 5.4: NE of ordinary PS for various illumination configurations."""
from __future__ import annotations

import numpy as np
import pandas as pd

from psbench.report.aggregates import long_frame, mean
from psbench.report.verdicts import (NE_MARGIN, verdict, nodata, lowest, rank, part_values,
                                     ok, num)

TITLE = "Table 5.4: NE for various illumination configurations"
AVERAGES = ("Mean NE over sombrero1-3, TS + shadows, 5 % noise, ordinary PS (mask None) "
            "on all images of the layout.")
NOTES = ""
GATED = True

# Mean NE of the three sombreros (TS, shadows, 5 % noise, no mask) per layout.
_NE = {
    "average": {"20x8+50x8": 5.96, "25x8+55x8": 5.83, "30x8+60x8": 5.51, "35x8+65x8": 5.33,
                "40x8+70x8": 5.57, "45x8+75x8": 6.21, "50x8+80x8": 7.53},
    "difference": {"5x8+85x8": 13.79, "10x8+80x8": 9.37, "15x8+75x8": 6.08,
                   "20x8+70x8": 5.16, "25x8+65x8": 4.85, "30x8+60x8": 5.01,
                   "35x8+55x8": 5.50, "40x8+50x8": 5.86},
    "multi": {"30x6+60x6": 5.73, "30x4+45x4+60x4": 5.72, "15x4+45x4+75x4": 6.35,
              "15x3+35x3+55x3+75x3": 6.27, "30x3+40x3+50x3+60x3": 5.80},
}
THESIS = {p: {cfg: {"ne": v} for cfg, v in d.items()} for p, d in _NE.items()}
#: layouts of each part, in the thesis's order
PARTS = {p: tuple(d) for p, d in _NE.items()}


def _records(df):
    recs = []
    if df.empty:
        return recs
    for part, cfgs in PARTS.items():
        for cfg in cfgs:
            g = df[df["lights"] == cfg]
            v, n = mean(g.get("ne_mean", pd.Series(dtype=float)))
            if n:
                recs.append((part, cfg, "ne", v, n))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    avg = {r: v for r, v in part_values(agg, "average", "ne").items()}
    dif = {r: v for r, v in part_values(agg, "difference", "ne").items()}
    mul = {r: v for r, v in part_values(agg, "multi", "ne").items()}
    out.append(lowest("35x8+65x8 is the best double-zenith configuration (average part)",
                      avg, "35x8+65x8"))
    if "30x8+60x8" in avg:
        r = rank(avg, "30x8+60x8")
        out.append(verdict("The rule of thumb's 30x8+60x8 is second best (average part)", r == 2,
                           f"rank {r} of {len(avg)} (NE {num(avg['30x8+60x8'])}); ranking: "
                           + ", ".join(f"{k} {num(v)}" for k, v in sorted(avg.items(),
                                                                          key=lambda kv: kv[1]))))
    else:
        out.append(nodata("The rule of thumb's 30x8+60x8 is second best (average part)"))
    if "30x8+60x8" in dif:
        r = rank(dif, "30x8+60x8")
        out.append(verdict("30x8+60x8 is second best in the zenith-difference part "
                           "(25x8+65x8 best)", r == 2,
                           f"rank {r} of {len(dif)}; ranking: " + ", ".join(
                               f"{k} {num(v)}" for k, v in sorted(dif.items(),
                                                                  key=lambda kv: kv[1]))))
    else:
        out.append(nodata("30x8+60x8 is second best in the zenith-difference part"))
    allr = {**avg, **dif}
    if "30x8+60x8" in allr:
        r = rank(allr, "30x8+60x8")
        out.append(verdict("The rule of thumb (Eq. 4.2) is a good prediction: 30x8+60x8 within "
                           "the best three double-zenith layouts", r is not None and r <= 3,
                           f"rank {r} of {len(allr)} over both parts"))
    a, b = mul.get("30x4+45x4+60x4"), mul.get("30x6+60x6")
    if ok(a) and ok(b):
        out.append(verdict("The triple ring 30x4+45x4+60x4 is slightly better than the double "
                           "30x6+60x6 (12 lights)", a < b,
                           f"{num(a)} vs {num(b)} (thesis 5.72 vs 5.73)",
                           undecided=abs(a - b) < NE_MARGIN))
        others = {k: v for k, v in mul.items() if k not in ("30x4+45x4+60x4", "30x6+60x6")}
        if others:
            out.append(verdict("Other multi-zenith layouts are not better than the double "
                               "30x6+60x6",
                               all(v >= b - NE_MARGIN for v in others.values()),
                               ", ".join(f"{k} {num(v)}" for k, v in others.items())
                               + f" vs 30x6+60x6 {num(b)}"))
    else:
        out.append(nodata("The triple ring 30x4+45x4+60x4 is slightly better than 30x6+60x6"))
    return out


PART_TITLES = {"average": "Two rings 30 deg apart, mean zenith varied",
               "difference": "Two rings around 45 deg, separation varied",
               "multi": "Three or four rings"}
_SHORT = {"average": "Two rings 30 deg apart\n(mean zenith varied)",
          "difference": "Two rings around 45 deg\n(separation varied)",
          "multi": "Three or four rings\n(12 lights)"}
TABLE_AXES = {"*": ("light layout (zenith x count + ...)", "")}


def figures(agg):
    """NE per layout, psbench beside the thesis, one panel per part."""
    from psbench.report.figures import figure_legend, finish, new_figure

    if agg is None or agg.empty:
        return []
    fig, axes = new_figure(ncols=3, w=4.6, h=5.4)
    for ax, (part, cfgs) in zip(axes, PARTS.items()):
        ps = []
        for cfg in cfgs:
            m = agg[(agg["part"] == part) & (agg["row"] == cfg)]
            ps.append(float(m["value"].iloc[0]) if len(m) else np.nan)
        y = np.arange(len(cfgs))[::-1]
        ax.barh(y + 0.2, ps, 0.4, label="psbench")
        ax.barh(y - 0.2, [THESIS[part][c]["ne"] for c in cfgs], 0.4, color="0.65",
                label="thesis (Table 5.4)")
        ax.set_yticks(y, cfgs)
        ax.grid(axis="y", visible=False)
        finish(ax, "mean NE (deg)", "", _SHORT[part], legend=False)
    figure_legend(fig)
    return [("table5_4", fig)]
