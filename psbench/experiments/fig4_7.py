"""Fig. 4.7: NE vs source zenith per sombrero, Di vs Hi-Sh."""
from __future__ import annotations

from psbench.report.aggregates import (long_frame, group_mean, fmt_num, model_label, labels,
                                       series)
from psbench.report.verdicts import (INCONCLUSIVE, NOT_SUPPORTED, SUPPORTED, Verdict, every,
                                     nodata, plateau, quoted)

TITLE = "Fig. 4.7: NE vs source zenith per sombrero, Di vs Hi-Sh"
AVERAGES = ("NE per sombrero, 8 lights, 5 % noise, Di (unclamped Lambert) vs Hi-Sh, vs "
            "source zenith.")
NOTES = ""
GATED = False

# Values quoted in the text: optimal source zeniths.
THESIS = {"quoted": {"optimum_zenith_HiSh": {"sombrero1": 70.0, "sombrero3": 45.0},
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


Q_OPT = ("line 848: \"For smooth sombrero1, (see Fig. 4.7a) the optimal Z_source was changed "
         "from 45° to 70° due to strong highlight errors with low Z_source. On the other "
         "hand, for rough sombrero3, (see Fig. 4.7c) the optimal Z_source was still increased "
         "but settled at 45° because of large shadow errors at high Z_source.\"")
Q_NONE = ("line 850: \"As a result, there is no single optimal value for every surface if "
          "highlights and shadows occur at the input images.\"")


def _status(sure, possible):
    return SUPPORTED if sure else (INCONCLUSIVE if possible else NOT_SUPPORTED)


def _opt_text(p):
    return "-".join(f"{z:g}" for z in (p[0], p[-1])) if len(p) > 1 else (f"{p[0]:g}" if p
                                                                          else "n/a")


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment. An optimum is
    the plateau of sampled zeniths within NE_MARGIN of a curve's minimum (a flat minimum
    does not single out one zenith): a claim is SUPPORTED when every zenith of the
    plateau satisfies it, NOT SUPPORTED when none does, INCONCLUSIVE otherwise."""
    out = []
    opt = {(s, lab): plateau(series(agg, s, lab))
           for s in ("sombrero1", "sombrero2", "sombrero3") for lab in ("Di", "Hi-Sh")}
    a, ad = opt[("sombrero1", "Hi-Sh")], opt[("sombrero1", "Di")]
    claim = "Smooth sombrero1 with Hi-Sh: optimal Z_source moves up to ~70 deg (>= 60)"
    out.append(Verdict("", claim, _status(min(a) >= 60, max(a) >= 60), f"optimum "
                       f"{_opt_text(a)} deg (Di {_opt_text(ad)} deg)", Q_OPT) if a else
               quoted(nodata(claim), Q_OPT))
    b, bd = opt[("sombrero3", "Hi-Sh")], opt[("sombrero3", "Di")]
    claim = "Rough sombrero3 with Hi-Sh: optimum stays at ~45 deg (40-50)"
    out.append(Verdict("", claim, _status(all(40 <= z <= 50 for z in b),
                                          any(40 <= z <= 50 for z in b)),
                       f"optimum {_opt_text(b)} deg (Di {_opt_text(bd)} deg)", Q_OPT) if b else
               quoted(nodata(claim), Q_OPT))
    parts = []
    for s in ("sombrero1", "sombrero2", "sombrero3"):
        h, d = opt[(s, "Hi-Sh")], opt[(s, "Di")]
        if h and d:   # raise or keep: the Hi-Sh optimum not below the lowest Di optimum
            parts.append(Verdict("", s, _status(min(h) >= min(d), max(h) >= min(d)),
                                 f"Di {_opt_text(d)} / Hi-Sh {_opt_text(h)}"))
    out.append(every("Highlights and shadows raise (or keep) the optimal Z_source", parts,
                     Q_OPT))
    hs = [set(opt[(s, "Hi-Sh")]) for s in ("sombrero1", "sombrero2", "sombrero3")
          if opt[(s, "Hi-Sh")]]
    claim = "There is no single optimal Z_source for every surface with Hi-Sh"
    if len(hs) > 1:
        shared = set.intersection(*hs)
        out.append(Verdict("", claim, NOT_SUPPORTED if shared else SUPPORTED,
                           ", ".join(f"{s} {_opt_text(opt[(s, 'Hi-Sh')])}" for s in
                                     ("sombrero1", "sombrero2", "sombrero3"))
                           + (f" (shared optimum {sorted(shared)})" if shared else ""), Q_NONE))
    else:
        out.append(quoted(nodata(claim), Q_NONE))
    return out


TABLE_AXES = {"*": ("images", "source zenith (deg)"), "quoted": ("quoted value", "surface")}
PART_TITLES = {"quoted": "Values quoted in the thesis's text",
               **{s: f"NE (deg) of {s}" for s in ("sombrero1", "sombrero2", "sombrero3")}}


def figures(agg):
    """NE vs source zenith per sombrero, Di vs Hi-Sh; the optima the thesis quotes as
    dashed lines."""
    from psbench.report.figures import figure_legend, finish, line, new_figure

    fig, axes = new_figure(ncols=3, w=4.6, h=4.8)
    for ax, s in zip(axes, ("sombrero1", "sombrero2", "sombrero3")):
        for lab in ("Di", "Hi-Sh"):
            line(ax, agg, s, lab)
            z = THESIS["quoted"][f"optimum_zenith_{lab.replace('-', '')}"].get(s)
            if z is not None:
                ax.axvline(z, color=ax.lines[-1].get_color() if ax.lines else "k", ls="--",
                           lw=1.5, label=f"thesis: optimum for {lab} (sombrero1, sombrero3)")
        finish(ax, "source zenith (deg)", "mean NE (deg)", s, legend=False)
    figure_legend(fig)
    return [("fig4_7", fig)]
