"""Fig. 4.7: NE vs source zenith per sombrero, Di vs Hi-Sh."""
from __future__ import annotations

from psbench.report.aggregates import (long_frame, group_mean, fmt_num, model_label, labels,
                                       series)
from psbench.report.verdicts import verdict, ok, num

TITLE = "Fig. 4.7: NE vs source zenith per sombrero, Di vs Hi-Sh"
AVERAGES = ("NE per sombrero, 8 lights, 5 % noise, Di (unclamped Lambert) vs Hi-Sh, vs "
            "source zenith.")
NOTES = ""
GATED = False

# Values quoted in the text: optimal source zeniths.
THESIS = {"": {"optimum_zenith_HiSh": {"sombrero1": 70.0, "sombrero3": 45.0},
               "optimum_zenith_Di": {"sombrero1": 45.0, "sombrero3": 45.0}}}


def _records(df):
    recs = []
    if df.empty:
        return recs
    d = df.copy()
    d["_lab"] = labels(d, model_label)
    group_mean(d, ["surface", "_lab", "zenith"], "ne_mean", recs, lambda k: str(k[0]),
               lambda k: k[1], lambda k: fmt_num(k[2]))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    opt = {}
    for s in ("sombrero1", "sombrero2", "sombrero3"):
        for lab in ("Di", "Hi-Sh"):
            ser = series(agg, s, lab)
            if len(ser):
                opt[(s, lab)] = float(ser.idxmin())
    a = opt.get(("sombrero1", "Hi-Sh"))
    out.append(verdict("Smooth sombrero1 with Hi-Sh: optimal Z_source moves up to ~70 deg "
                       "(>= 60)", (a >= 60) if ok(a) else None,
                       f"optimum {num(a, 0)} deg (Di {num(opt.get(('sombrero1', 'Di')), 0)} deg)"))
    b = opt.get(("sombrero3", "Hi-Sh"))
    out.append(verdict("Rough sombrero3 with Hi-Sh: optimum stays at ~45 deg (40-50)",
                       (40 <= b <= 50) if ok(b) else None,
                       f"optimum {num(b, 0)} deg (Di {num(opt.get(('sombrero3', 'Di')), 0)} deg)"))
    ups = [opt[(s, "Hi-Sh")] >= opt[(s, "Di")] for s in ("sombrero1", "sombrero2", "sombrero3")
           if (s, "Hi-Sh") in opt and (s, "Di") in opt]
    out.append(verdict("Highlights and shadows raise (or keep) the optimal Z_source",
                       all(ups) if ups else None,
                       ", ".join(f"{s}: Di {num(opt.get((s, 'Di')), 0)} / Hi-Sh "
                                 f"{num(opt.get((s, 'Hi-Sh')), 0)}"
                                 for s in ("sombrero1", "sombrero2", "sombrero3"))))
    if len({v for (s, lab), v in opt.items() if lab == "Hi-Sh"}) > 1:
        out.append(verdict("There is no single optimal Z_source for every surface with Hi-Sh", True,
                           ", ".join(f"{s} {num(v, 0)}" for (s, lab), v in opt.items()
                                     if lab == "Hi-Sh")))
    elif opt:
        out.append(verdict("There is no single optimal Z_source for every surface with Hi-Sh",
                           False, "all sombreros share one optimum"))
    return out


def figures(agg):
    from psbench.report.figures import finish, line, new_figure

    fig, axes = new_figure(ncols=3, w=3.6)
    for ax, s in zip(axes, ("sombrero1", "sombrero2", "sombrero3")):
        for lab in ("Di", "Hi-Sh"):
            line(ax, agg, s, lab)
        finish(ax, "source zenith (deg)", "NE (deg)", s)
    fig.tight_layout()
    return [("fig4_7", fig)]
