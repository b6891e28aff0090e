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


def figures(agg):
    from psbench.report.figures import finish, new_figure

    if agg is None or agg.empty:
        return []
    fig, (ax,) = new_figure(w=7.5, h=3.6)
    labels, ps, th = [], [], []
    for part, cfgs in PARTS.items():
        for cfg in cfgs:
            m = agg[(agg["part"] == part) & (agg["row"] == cfg)]
            labels.append(cfg)
            ps.append(float(m["value"].iloc[0]) if len(m) else np.nan)
            th.append(THESIS[part][cfg]["ne"])
    x = np.arange(len(labels))
    ax.bar(x - 0.2, ps, 0.4, label="psbench")
    ax.bar(x + 0.2, th, 0.4, label="thesis")
    ax.set_xticks(x, labels, rotation=70, fontsize=6)
    finish(ax, "", "NE (deg)", "Table 5.4")
    fig.tight_layout()
    return [("table5_4", fig)]
