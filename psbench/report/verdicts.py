"""One verdict per qualitative conclusion of the thesis, decided on psbench's aggregates.

Each check returns :class:`Verdict` with ``status`` in ``SUPPORTED``, ``NOT SUPPORTED`` or
``INCONCLUSIVE`` and a ``detail`` string holding the numbers it was decided on. A claim
whose data are missing is INCONCLUSIVE ("no data"); a comparison whose two sides differ
by less than a stated margin (e.g. 0.1 deg of NE) is INCONCLUSIVE rather than decided
by noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from . import thesis_values as tv
from .tables import lookup, series

SUPPORTED, NOT_SUPPORTED, INCONCLUSIVE = "SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE"
NE_MARGIN = 0.1  # degrees: NE differences below this are not decided


@dataclass
class Verdict:
    experiment: str
    claim: str          # the thesis's conclusion, in one line
    status: str
    detail: str         # psbench's numbers (and the thesis's)

    def as_dict(self):
        return {"experiment": self.experiment, "claim": self.claim, "status": self.status,
                "detail": self.detail}


def _ok(x) -> bool:
    return x is not None and not (isinstance(x, float) and math.isnan(x))


def _f(x, nd=2) -> str:
    return "n/a" if not _ok(x) else f"{x:.{nd}f}"


def _v(exp, claim, cond, detail, undecided=False):
    if cond is None:
        return Verdict(exp, claim, INCONCLUSIVE, detail or "no data")
    if undecided:
        return Verdict(exp, claim, INCONCLUSIVE, detail)
    return Verdict(exp, claim, SUPPORTED if cond else NOT_SUPPORTED, detail)


def _nodata(exp, claim):
    return Verdict(exp, claim, INCONCLUSIVE, "no data in the store for this claim")


def _part(agg, part, column):
    """{row: value} of one part/column."""
    if agg is None or agg.empty:
        return {}
    m = agg[(agg["part"] == part) & (agg["column"] == column)]
    return {r: float(v) for r, v in zip(m["row"], m["value"]) if _ok(float(v))}


def _lowest(exp, claim, values: dict, who: str, margin=NE_MARGIN, unit="deg"):
    if not values or who not in values:
        return _nodata(exp, claim)
    best = min(values, key=values.get)
    ranked = sorted(values.items(), key=lambda kv: kv[1])
    top = ", ".join(f"{k} {_f(v)}" for k, v in ranked[:4])
    if best == who:
        return _v(exp, claim, True, f"{who} lowest ({_f(values[who])} {unit}); ranking: {top}")
    gap = values[who] - values[best]
    return _v(exp, claim, False, f"{who} {_f(values[who])} vs best {best} {_f(values[best])} "
              f"(gap {_f(gap)} {unit}{' < margin' if gap < margin else ''}); ranking: {top}",
              undecided=gap < margin)


def _rank(values: dict, who: str):
    ranked = sorted(values, key=values.get)
    return ranked.index(who) + 1 if who in ranked else None


# ----------------------------------------------------------------------------- per table

def v_table2_1(agg, rows=None):
    e = "table2_1"
    out = []
    c4, c8 = series(agg, "", "4"), series(agg, "", "8")
    if c4.empty or c8.empty:
        return [_nodata(e, "The number of light sources does not change the condition value"),
                _nodata(e, "Larger zenith angles have a better (smaller) condition value")]
    common = c4.index.intersection(c8.index)
    dmax = float(np.max(np.abs(c4[common] - c8[common]))) if len(common) else float("nan")
    out.append(_v(e, "The number of light sources does not change the condition value",
                  dmax < 1e-3 if _ok(dmax) else None,
                  f"max |cond(4 lights) - cond(8 lights)| = {dmax:.2e} over zeniths "
                  f"{', '.join(_fmt(z) for z in common)}"))
    mono = all(bool((np.diff(s.to_numpy()) < 0).all()) for s in (c4, c8))
    out.append(_v(e, "Larger zenith angles have a better (smaller) condition value", bool(mono),
                  "4 lights: " + ", ".join(f"{_fmt(z)}deg {v:.4f}" for z, v in c4.items())))
    th = tv.VALUES["table2_1"][""]
    errs = [abs(float(v) - th[n][_fmt(z)]) for n, s in (("4", c4), ("8", c8))
            for z, v in s.items() if _fmt(z) in th[n]]
    if errs:
        out.append(_v(e, "psbench reproduces every printed condition value (to 1e-3)",
                      max(errs) < 1e-3, f"max |psbench - thesis| = {max(errs):.2e} over "
                      f"{len(errs)} cells"))
    return out


def _fmt(z):
    z = float(z)
    return str(int(z)) if z == int(z) else f"{z:g}"


def v_table5_2(agg, rows=None):
    e = "table5_2"
    out = []
    opt = {} if agg is None or agg.empty else {
        (r, c): v for p, r, c, v in agg[agg["part"] == "optimum"][["part", "row", "column",
                                                                     "value"]].itertuples(
            index=False)}
    claim = "Tuned threshold values increase from 4 to 12 images (k_low, k_Hi)"
    parts = []
    votes = []
    for name in ("k_low", "k_Hi"):
        v4, v12 = opt.get((name, "4")), opt.get((name, "12"))
        if _ok(v4) and _ok(v12):
            votes.append(int(np.sign(round(v12 - v4, 9))))
            parts.append(f"{name}: 4 img {_f(v4, 3)} -> 12 img {_f(v12, 3)} "
                         f"(thesis {tv.value('table5_2', '', name, '4')} -> "
                         f"{tv.value('table5_2', '', name, '12')})")
    # votes: +1 increased, 0 equal, -1 decreased
    out.append(_v(e, claim, (min(votes) >= 0 and max(votes) > 0) if votes else None,
                  "; ".join(parts), undecided=bool(votes) and max(votes) == 0 == min(votes)))
    # closeness of each tuned value to Table 5.2
    cells = []
    for name in ("k_low", "k_up", "k_Hi", "k_CS", "t_NL"):
        for n in ("4", "6", "8", "12"):
            v = opt.get((name, n))
            if _ok(v):
                cells.append(f"{name}[{n}] {_f(v, 3)} (thesis {tv.value('table5_2', '', name, n)})")
    close = []
    for name in ("k_low", "k_up", "k_Hi", "k_CS", "t_NL"):
        for n in ("4", "6", "8", "12"):
            v, t = opt.get((name, n)), tv.value("table5_2", "", name, n)
            if _ok(v):
                close.append(v == t or (t != 0 and 0.5 <= v / t <= 2.0))
    out.append(_v(e, "psbench's QF-optimal thresholds agree with Table 5.2 within a factor of 2 "
                  "(>= 75 % of the cells)", (sum(close) >= 0.75 * len(close)) if close else None,
                  f"{sum(close)}/{len(close)} cells within a factor 2: " + "; ".join(cells)))
    # noise dependence: optimum at noise 0.2 >= at 0 (most thresholds), except t_Re
    q = agg[agg["part"] == "qf"] if agg is not None and not agg.empty else pd.DataFrame()
    ups, parts = [], []
    if not q.empty:
        q = q.assign(name=q["row"].str.split("=").str[0],
                     val=pd.to_numeric(q["row"].str.split("=").str[1], errors="coerce"),
                     noise=q["column"].str.split("/").str[1])
        for name, g in q.groupby("name"):
            if name == "t_Re":
                continue
            best = {}
            for nz, gg in g.groupby("noise"):
                m = gg.groupby("val")["value"].mean()
                if len(m):
                    best[nz] = float(m.idxmax())
            if "0" in best and "0.2" in best:
                d = best["0.2"] - best["0"]
                ups.append(d > 1e-12 if name != "k_CS" else d < -1e-12)
                parts.append(f"{name}: {_f(best['0'], 3)} (no noise) -> {_f(best['0.2'], 3)} (20 %)")
    out.append(_v(e, "Threshold magnitudes grow with noise for most masks (Fig. 5.10 left; "
                  "strict increase from no noise to 20 % counted)",
                  (sum(ups) > len(ups) / 2) if ups else None, "; ".join(parts)))
    reo = {} if agg is None or agg.empty else {
        c: v for r, c, v in agg[agg["part"] == "re_optimum"][["row", "column", "value"]]
        .itertuples(index=False)}
    if reo:
        diffs, parts = [], []
        for z, v in sorted(reo.items(), key=lambda kv: float(kv[0])):
            f = tv.t_re_formula(float(z), 8)
            diffs.append(abs(v - f))
            parts.append(f"Z={z}: NE-optimal t_Re {_f(v, 0)} vs Eq. 5.1 {_f(f, 1)}")
        out.append(_v(e, "Eq. 5.1 t_Re = min(z, (90-z)/2, p) predicts the NE-optimal t_Re "
                      "(within one 5-deg sweep step)", max(diffs) <= 5.0 + 1e-9, "; ".join(parts)))
    else:
        out.append(_nodata(e, "Eq. 5.1 t_Re = min(z, (90-z)/2, p) predicts the NE-optimal t_Re"))
    return out


def v_table5_3(agg, rows=None):
    e = "table5_3"
    out = []
    ne = _part(agg, "all", "ne")
    ne4 = _part(agg, "four", "ne")
    t = _part(agg, "all", "time")
    qf = _part(agg, "all", "qf_total")
    out.append(_lowest(e, "Th-Hi-Re-Sh has the lowest NE (all light sources)", ne, "Th-Hi-Re-Sh"))
    if "Th" in ne and "Th-Hi-Re-Sh" in ne:
        d = ne["Th"] - ne["Th-Hi-Re-Sh"]
        out.append(_v(e, "Th alone is within 1 deg of Th-Hi-Re-Sh", 0 <= d < 1.0 or abs(d) < 1.0,
                      f"Th {_f(ne['Th'])} - Th-Hi-Re-Sh {_f(ne['Th-Hi-Re-Sh'])} = {_f(d)} deg "
                      f"(thesis 8.63 - 8.28 = 0.35)"))
    else:
        out.append(_nodata(e, "Th alone is within 1 deg of Th-Hi-Re-Sh"))
    if "Th" in t and "Th-Hi-Re-Sh" in t and t["Th"] > 0:
        r = t["Th-Hi-Re-Sh"] / t["Th"]
        out.append(_v(e, "Th-Hi-Re-Sh costs several times Th's time (thesis: ~8-12x)", r >= 3.0,
                      f"t(Th-Hi-Re-Sh)/t(Th) = {_f(r, 1)} ({_f(t['Th-Hi-Re-Sh'], 3)} s / "
                      f"{_f(t['Th'], 3)} s; thesis 20.12/1.67 = 12.0)"))
    else:
        out.append(_nodata(e, "Th-Hi-Re-Sh costs several times Th's time"))
    if "None" in ne and "xNL" in ne:
        d = ne["None"] - ne["xNL"]
        out.append(_v(e, "xNL reduces NE w.r.t. None", d > 0,
                      f"None {_f(ne['None'])} -> xNL {_f(ne['xNL'])} (thesis 14.78 -> 11.37)",
                      undecided=abs(d) < NE_MARGIN))
    else:
        out.append(_nodata(e, "xNL reduces NE w.r.t. None"))
    if "xNL" in ne and "xNL-Sh" in ne:
        d = ne["xNL"] - ne["xNL-Sh"]
        out.append(_v(e, "Adding Sh to xNL (xNL-Sh) improves NE", d > 0,
                      f"xNL {_f(ne['xNL'])} -> xNL-Sh {_f(ne['xNL-Sh'])} (thesis 11.37 -> 11.36)",
                      undecided=abs(d) < NE_MARGIN))
    if "Th" in ne and ne:
        others = {k: v for k, v in ne.items() if "-" not in k}
        out.append(_lowest(e, "Th is the best single mask", others, "Th"))
    if "RA" in ne and "None" in ne:
        d = ne["None"] - ne["RA"]
        out.append(_v(e, "RA (all light sources) improves slightly on None", d > 0,
                      f"None {_f(ne['None'])} vs RA {_f(ne['RA'])} (thesis 14.78 vs 13.23)",
                      undecided=abs(d) < NE_MARGIN))
    else:
        out.append(_nodata(e, "RA (all light sources) improves slightly on None"))
    if "RA" in ne4 and "None" in ne4:
        d = ne4["RA"] - ne4["None"]
        out.append(_v(e, "RA with 4 lights is worse than None", d > 0,
                      f"4 lights: RA {_f(ne4['RA'])} vs None {_f(ne4['None'])} "
                      f"(thesis 17.72 vs 15.18)", undecided=abs(d) < NE_MARGIN))
    else:
        out.append(_nodata(e, "RA with 4 lights is worse than None"))
    out.append(_lowest(e, "With 4 lights, Barsky's NL-Re performs (slightly) best",
                       {k: v for k, v in ne4.items()}, "NL-Re"))
    if "CJ" in ne4 and ne4:
        masked = {k: v for k, v in ne4.items() if k not in ("None", "CJ", "RA")}
        if masked:
            worst = max(masked.values())
            out.append(_v(e, "With 4 lights CJ is worse than the other masking methods "
                          "(NL-Re, Th, NL-Re-Sh)", ne4["CJ"] > worst,
                          f"CJ {_f(ne4['CJ'])} vs " + ", ".join(f"{k} {_f(v)}"
                                                                for k, v in masked.items()),
                          undecided=abs(ne4["CJ"] - worst) < NE_MARGIN))
    else:
        out.append(_nodata(e, "With 4 lights CJ is worse than the other masking methods"))
    if qf and "Th" in qf:
        best = max(qf, key=qf.get)
        out.append(_v(e, "Th has the highest total QF", best == "Th",
                      f"Th {_f(qf['Th'])}; best {best} {_f(qf[best])} (thesis Th 0.64)"))
    else:
        out.append(_nodata(e, "Th has the highest total QF"))
    return out


def v_table5_4(agg, rows=None):
    e = "table5_4"
    out = []
    avg = {r: v for r, v in _part(agg, "average", "ne").items()}
    dif = {r: v for r, v in _part(agg, "difference", "ne").items()}
    mul = {r: v for r, v in _part(agg, "multi", "ne").items()}
    out.append(_lowest(e, "35x8+65x8 is the best double-zenith configuration (average part)",
                       avg, "35x8+65x8"))
    if "30x8+60x8" in avg:
        r = _rank(avg, "30x8+60x8")
        out.append(_v(e, "The rule of thumb's 30x8+60x8 is second best (average part)", r == 2,
                      f"rank {r} of {len(avg)} (NE {_f(avg['30x8+60x8'])}); ranking: "
                      + ", ".join(f"{k} {_f(v)}" for k, v in sorted(avg.items(),
                                                                  key=lambda kv: kv[1]))))
    else:
        out.append(_nodata(e, "The rule of thumb's 30x8+60x8 is second best (average part)"))
    if "30x8+60x8" in dif:
        r = _rank(dif, "30x8+60x8")
        out.append(_v(e, "30x8+60x8 is second best in the zenith-difference part "
                      "(25x8+65x8 best)", r == 2,
                      f"rank {r} of {len(dif)}; ranking: " + ", ".join(
                          f"{k} {_f(v)}" for k, v in sorted(dif.items(), key=lambda kv: kv[1]))))
    else:
        out.append(_nodata(e, "30x8+60x8 is second best in the zenith-difference part"))
    allr = {**avg, **dif}
    if "30x8+60x8" in allr:
        r = _rank(allr, "30x8+60x8")
        out.append(_v(e, "The rule of thumb (Eq. 4.2) is a good prediction: 30x8+60x8 within "
                      "the best three double-zenith layouts", r is not None and r <= 3,
                      f"rank {r} of {len(allr)} over both parts"))
    a, b = mul.get("30x4+45x4+60x4"), mul.get("30x6+60x6")
    if _ok(a) and _ok(b):
        out.append(_v(e, "The triple ring 30x4+45x4+60x4 is slightly better than the double "
                      "30x6+60x6 (12 lights)", a < b,
                      f"{_f(a)} vs {_f(b)} (thesis 5.72 vs 5.73)", undecided=abs(a - b) < NE_MARGIN))
        others = {k: v for k, v in mul.items() if k not in ("30x4+45x4+60x4", "30x6+60x6")}
        if others:
            out.append(_v(e, "Other multi-zenith layouts are not better than the double 30x6+60x6",
                          all(v >= b - NE_MARGIN for v in others.values()),
                          ", ".join(f"{k} {_f(v)}" for k, v in others.items())
                          + f" vs 30x6+60x6 {_f(b)}"))
    else:
        out.append(_nodata(e, "The triple ring 30x4+45x4+60x4 is slightly better than 30x6+60x6"))
    return out


def v_table5_5(agg, rows=None):
    e = "table5_5"
    out = []
    one, two = series(agg, "ne", "1Z/None"), series(agg, "ne", "2Z/None")
    common = one.index.intersection(two.index)
    big = [n for n in common if n > 4]
    if big:
        wins = [two[n] < one[n] for n in big]
        out.append(_v(e, "2Z beats 1Z for n_i > 4 with highlights and shadows (ordinary PS)",
                      all(wins), ", ".join(f"n={int(n)}: 1Z {_f(one[n])} / 2Z {_f(two[n])}"
                                           for n in big),
                      undecided=not all(wins) and any(wins)))
        gaps = [one[n] - two[n] for n in big]
        out.append(_v(e, "The 2Z advantage grows with the image count", gaps[-1] > gaps[0],
                      f"1Z-2Z gap: " + ", ".join(f"n={int(n)} {_f(g)}" for n, g in zip(big, gaps))))
    else:
        out.append(_nodata(e, "2Z beats 1Z for n_i > 4 with highlights and shadows"))
    best = series(agg, "improvement", "2Z/eZsourceZsurface")
    if not best.empty:
        out.append(_v(e, "eZsourceZsurface improves on 1Z by >= 30 % at every n_i",
                      bool((best >= 30).all()),
                      ", ".join(f"n={int(n)} {_f(v, 1)} %" for n, v in best.items())
                      + " (thesis 31.6-39.6 %)"))
    else:
        out.append(_nodata(e, "eZsourceZsurface improves on 1Z by >= 30 %"))
    rowsw = [r for r in tv.T55_ROWS if r.startswith("2Z/")]
    mean_ne = {r: float(series(agg, "ne", r).mean()) for r in rowsw
               if not series(agg, "ne", r).empty}
    out.append(_lowest(e, "eZsourceZsurface is the best weight (lowest NE averaged over n_i)",
                       mean_ne, "2Z/eZsourceZsurface"))
    wps = {r: v for r, v in mean_ne.items() if r != "2Z/None"}
    if wps and "2Z/None" in mean_ne:
        out.append(_v(e, "Every WPS weight improves on 2Z PS (mean over n_i)",
                      all(v < mean_ne["2Z/None"] for v in wps.values()),
                      f"2Z PS {_f(mean_ne['2Z/None'])}; " + ", ".join(
                          f"{k[3:]} {_f(v)}" for k, v in wps.items())))
    if not one.empty and not two.empty and 8 in one.index and 32 in one.index \
            and 8 in two.index and 32 in two.index:
        i1 = 100 * (one[8] - one[32]) / one[8]
        i2 = 100 * (two[8] - two[32]) / two[8]
        out.append(_v(e, "From 8 to 32 images 1Z improves little (~4 %) while 2Z improves > 10 %",
                      i1 < 10 and i2 > 10 and i2 > i1,
                      f"1Z {_f(i1, 1)} %, 2Z {_f(i2, 1)} % (thesis 4.1 %, 14.0 %)"))
    di1, di2 = series(agg, "di", "1Z/None"), series(agg, "di", "2Z/None")
    cd = di1.index.intersection(di2.index)
    if len(cd):
        wins = [di1[n] <= di2[n] for n in cd]
        out.append(_v(e, "Diffuse images: 1Z NE is always below 2Z (Fig. 5.22)", all(wins),
                      ", ".join(f"n={int(n)}: 1Z {_f(di1[n])} / 2Z {_f(di2[n])}" for n in cd)))
    else:
        out.append(_nodata(e, "Diffuse images: 1Z NE is always below 2Z (Fig. 5.22)"))
    return out


def v_table5_6(agg, rows=None):
    e = "table5_6"
    w, b = lookup(agg, "", "weighted", "mean"), lookup(agg, "", "binary", "mean")
    if not (_ok(w) and _ok(b)):
        return [_nodata(e, "Binary beats weighted fusion on NE (mean of the sombreros)")]
    out = [_v(e, "Binary beats weighted fusion on NE (mean of the sombreros)", b < w,
              f"binary {_f(b)} vs weighted {_f(w)} (thesis 5.19 vs 5.65)",
              undecided=abs(b - w) < NE_MARGIN)]
    w3, b3 = lookup(agg, "", "weighted", "sombrero3"), lookup(agg, "", "binary", "sombrero3")
    if _ok(w3) and _ok(b3):
        out.append(_v(e, "...except on the roughest sombrero3, where weighted is better",
                      w3 < b3, f"sombrero3: weighted {_f(w3)} vs binary {_f(b3)} "
                      f"(thesis 6.74 vs 7.00)", undecided=abs(w3 - b3) < NE_MARGIN))
    return out


def v_table6_1(agg, rows=None):
    e = "table6_1"
    out = []
    if agg is None or agg.empty:
        return [_nodata(e, "WPS reduces IE w.r.t. PS for every weight"),
                _nodata(e, "e weights give the lowest IE on real images")]
    eq230 = lookup(agg, "info", "WPS IE is Eq. 2.30 (1) or Eq. 2.29 (0)", "value") == 1.0
    for lay in sorted(p for p in agg["part"].unique() if p != "info"):
        ov = {r: v for r, v in _part(agg, lay, "overall").items()}
        wps = {k: v for k, v in ov.items() if k != "None"}
        if wps and eq230:
            out.append(_v(e, f"WPS reduces IE w.r.t. 2Z PS for every weight ({lay})",
                          all(v < 100 for v in wps.values()),
                          ", ".join(f"{k} {_f(v, 1)} %" for k, v in wps.items())
                          + " (Eq. 2.30 IE of WPS vs Eq. 2.29 IE of PS)"))
            out.append(_lowest(e, f"e weights give the lowest IE on real images ({lay})", wps,
                               "e", margin=0.5, unit="%"))
        elif wps:
            # The store's ie_* of a WPS row is Eq. 2.29 over all images with the fused
            # normals; the least-squares PS solution minimizes exactly that residual, so
            # no WPS row can be below 100 % under it. The thesis's Table 6.1 uses the
            # weighted per-ring IE of Eq. 2.30. Below 100 % would decide the claim; at or
            # above 100 % it cannot be decided with this IE definition.
            below = all(v < 100 for v in wps.values())
            out.append(_v(e, f"WPS reduces IE w.r.t. 2Z PS for every weight ({lay})", below,
                          ", ".join(f"{k} {_f(v, 1)} %" for k, v in wps.items())
                          + ("" if below else " -- stored IE is Eq. 2.29 (fused normals, all "
                             "images), which cannot fall below the PS least-squares residual; "
                             "the thesis uses the weighted per-ring IE of Eq. 2.30"),
                          undecided=not below))
            out.append(_lowest(e, f"e weights give the lowest IE on real images ({lay})", wps,
                               "e", margin=0.5, unit="%"))
    return out or [_nodata(e, "WPS reduces IE w.r.t. PS for every weight")]


def v_table6_2(agg, rows=None):
    e = "table6_2"
    if agg is None or agg.empty:
        return [_nodata(e, "WPS costs about 3x PS")]
    out = []
    for lay in sorted(agg["column"].unique()):
        r = {k: v for k, v in _part(agg, "", lay).items() if k != "None"}
        if r:
            m = float(np.mean(list(r.values())))
            out.append(_v(e, f"WPS costs about 3x PS (2-4x; {lay})", 2.0 <= m <= 4.0,
                          ", ".join(f"{k} {_f(v)}x" for k, v in r.items())
                          + f"; mean {_f(m)}x (thesis 2.6-3.1x)"))
    return out or [_nodata(e, "WPS costs about 3x PS")]


def v_fig4_3(agg, rows=None):
    e = "fig4_3"
    out = []
    for lab, lim, th in (("Di", 5.0, "1.44 -> 1.38, 4 %"), ("Hi-Sh", 2.0, "9.34 -> 9.25, 1 %")):
        s = series(agg, "", lab)
        if 16 in s.index and 32 in s.index:
            d = 100 * (s[16] - s[32]) / s[16]
            out.append(_v(e, f"NE saturates with n_i: 16 -> 32 images changes {lab} NE by "
                          f"< {lim:g} %", d < lim, f"{_f(s[16])} -> {_f(s[32])} ({_f(d, 1)} %; "
                          f"thesis {th})"))
        else:
            out.append(_nodata(e, f"NE saturates with n_i ({lab})"))
    return out


def v_fig4_4(agg, rows=None):
    e = "fig4_4"
    if agg is None or agg.empty:
        return [_nodata(e, "Z_source = 45 deg is optimal for diffuse images at every n_i")]
    opts = {}
    for n in sorted(agg["row"].unique(), key=float):
        s = series(agg, "", n)
        if len(s):
            opts[n] = float(s.idxmin())
    ok = all(40 <= z <= 50 for z in opts.values())
    return [_v(e, "Z_source = 45 deg is optimal for diffuse images at every n_i (40-50 deg)", ok,
               ", ".join(f"n={k}: {_f(v, 0)} deg" for k, v in opts.items()))]


def v_fig4_7(agg, rows=None):
    e = "fig4_7"
    out = []
    opt = {}
    for s in ("sombrero1", "sombrero2", "sombrero3"):
        for lab in ("Di", "Hi-Sh"):
            ser = series(agg, s, lab)
            if len(ser):
                opt[(s, lab)] = float(ser.idxmin())
    a = opt.get(("sombrero1", "Hi-Sh"))
    out.append(_v(e, "Smooth sombrero1 with Hi-Sh: optimal Z_source moves up to ~70 deg "
                  "(>= 60)", (a >= 60) if _ok(a) else None,
                  f"optimum {_f(a, 0)} deg (Di {_f(opt.get(('sombrero1', 'Di')), 0)} deg)"))
    b = opt.get(("sombrero3", "Hi-Sh"))
    out.append(_v(e, "Rough sombrero3 with Hi-Sh: optimum stays at ~45 deg (40-50)",
                  (40 <= b <= 50) if _ok(b) else None,
                  f"optimum {_f(b, 0)} deg (Di {_f(opt.get(('sombrero3', 'Di')), 0)} deg)"))
    ups = [opt[(s, "Hi-Sh")] >= opt[(s, "Di")] for s in ("sombrero1", "sombrero2", "sombrero3")
           if (s, "Hi-Sh") in opt and (s, "Di") in opt]
    out.append(_v(e, "Highlights and shadows raise (or keep) the optimal Z_source", all(ups)
                  if ups else None, ", ".join(f"{s}: Di {_f(opt.get((s, 'Di')), 0)} / Hi-Sh "
                                              f"{_f(opt.get((s, 'Hi-Sh')), 0)}"
                                              for s in ("sombrero1", "sombrero2", "sombrero3"))))
    if len({v for (s, lab), v in opt.items() if lab == "Hi-Sh"}) > 1:
        out.append(_v(e, "There is no single optimal Z_source for every surface with Hi-Sh", True,
                      ", ".join(f"{s} {_f(v, 0)}" for (s, lab), v in opt.items()
                                if lab == "Hi-Sh")))
    elif opt:
        out.append(_v(e, "There is no single optimal Z_source for every surface with Hi-Sh",
                      False, "all sombreros share one optimum"))
    return out


def v_fig4_6(agg, rows=None):
    e = "fig4_6"
    out = []
    if agg is None or agg.empty:
        return [_nodata(e, "Highlight IE falls and shadow IE rises with Z_source")]
    hv, sv = [], []
    for s in sorted(agg["part"].unique()):
        h, sh = series(agg, s, "highlight"), series(agg, s, "shadow")
        if len(h) > 1:
            hv.append(h.iloc[-1] < h.iloc[0])
        if len(sh) > 1:
            sv.append(sh.iloc[-1] > sh.iloc[0])
    out.append(_v(e, "Highlight IE falls with Z_source on every sombrero", all(hv) if hv else None,
                  f"{sum(hv)}/{len(hv)} sombreros"))
    out.append(_v(e, "Shadow IE rises with Z_source on every sombrero", all(sv) if sv else None,
                  f"{sum(sv)}/{len(sv)} sombreros"))
    return out


def v_fig4_9(agg, rows=None):
    e = "fig4_9"
    s30, s60 = series(agg, "", "30"), series(agg, "", "60")
    out = []
    if len(s30) > 2:
        peak = float(s30.idxmax())
        out.append(_v(e, "At Z_source = 30 deg, NE concentrates at low Z_surface (highlights, "
                      "around Z_source/2)", peak <= 35,
                      f"NE peak at Z_surface {_f(peak, 0)} deg"))
    else:
        out.append(_nodata(e, "At Z_source = 30 deg, NE concentrates at low Z_surface"))
    if len(s60) > 2:
        x = np.asarray(s60.index, float)
        slope = float(np.polyfit(x, s60.to_numpy(), 1)[0])
        out.append(_v(e, "At Z_source = 60 deg, NE increases with Z_surface", slope > 0,
                      f"linear slope {slope:.3f} deg/deg"))
    else:
        out.append(_nodata(e, "At Z_source = 60 deg, NE increases with Z_surface"))
    return out


def v_fig4_10(agg, rows=None):
    e = "fig4_10"
    out = []
    if agg is None or agg.empty:
        return [_nodata(e, "Highlight IE peaks near Z_surface = Z_source/2")]
    for z in sorted(agg["part"].unique(), key=float):
        h = series(agg, z, "highlight")
        if len(h) > 2:
            peak = float(h.idxmax())
            out.append(_v(e, f"Z_source {z}: highlight IE peaks near Z_surface = Z_source/2 "
                          f"(+-10 deg)", abs(peak - float(z) / 2) <= 10,
                          f"peak at {_f(peak, 0)} deg, Z_source/2 = {_f(float(z) / 2, 1)}"))
        sh = series(agg, z, "shadow")
        lim = 90.0 - float(z)
        below, above = sh[sh.index < lim], sh[sh.index >= lim]
        if len(below) and len(above):
            out.append(_v(e, f"Z_source {z}: shadow IE rises beyond Z_surface = 90 - Z_source",
                          float(above.mean()) > float(below.mean()),
                          f"mean shadow IE {_f(float(below.mean()))} below {_f(lim, 0)} deg vs "
                          f"{_f(float(above.mean()))} above"))
    return out or [_nodata(e, "Highlight IE peaks near Z_surface = Z_source/2")]


def _slope(s):
    if len(s) < 2:
        return float("nan")
    x = np.asarray(s.index, float)
    return float(np.polyfit(x, s.to_numpy(), 1)[0])


def v_fig5_12(agg, rows=None):
    e = "fig5_12"
    out = []
    fams = ["None", "NL", "Th", "NL-Sh", "Th-Hi-Re-Sh", "RA"]
    s = {f: series(agg, "", f) for f in fams}
    sl = {f: _slope(v) for f, v in s.items() if len(v) > 1}
    if not sl:
        return [_nodata(e, "NE increases with noise for every mask")]
    out.append(_v(e, "NE increases with noise for every mask", all(v > 0 for v in sl.values()),
                  ", ".join(f"{k} {v:.1f} deg/unit noise" for k, v in sl.items())))
    if "None" in sl:
        masked = {k: v for k, v in sl.items() if k != "None"}
        out.append(_v(e, "Masked PS is more noise-sensitive than None (steeper NE vs noise)",
                      all(v > sl["None"] for v in masked.values()),
                      f"None {sl['None']:.1f}; " + ", ".join(f"{k} {v:.1f}"
                                                             for k, v in masked.items())))
    if "Th" in sl and "NL" in sl:
        out.append(_v(e, "Th is less noise-sensitive than NL (NL more noise-sensitive)",
                      sl["Th"] < sl["NL"], f"slopes Th {sl['Th']:.1f} vs NL {sl['NL']:.1f}"))
    if "NL" in sl:
        steep = max(sl, key=sl.get)
        rank = ", ".join(f"{k} {v:.1f}" for k, v in sorted(sl.items(), key=lambda kv: -kv[1]))
        out.append(_v(e, "NL is the most noise-sensitive of the selected masks (steepest NE vs "
                         "noise; the thesis states NL > Th and calls RA very sensitive)",
                      steep == "NL", f"steepest: {steep}; slopes (deg per unit noise): {rank}",
                      undecided=steep != "NL" and sl[steep] - sl["NL"] < 1.0))
    if "RA" in s and "None" in s and len(s["RA"]):
        hi = [n for n in s["RA"].index if n > 0.15 and n in s["None"].index]
        lo = [n for n in s["RA"].index if n <= 0.05 and n in s["None"].index]
        if hi:
            out.append(_v(e, "RA becomes worse than None above 15 % noise",
                          all(s["RA"][n] > s["None"][n] for n in hi),
                          ", ".join(f"noise {n:g}: RA {_f(s['RA'][n])} / None {_f(s['None'][n])}"
                                    for n in lo + hi)))
    return out


def v_fig5_13(agg, rows=None):
    e = "fig5_13"
    out = []
    s = {f: series(agg, "", f) for f in ("None", "NL", "Th", "NL-Sh", "Th-Hi-Re-Sh", "RA")}
    ra, no = s["RA"], s["None"]
    if len(ra) and len(no):
        n4 = 4.0 in ra.index and 4.0 in no.index and ra[4.0] > no[4.0]
        ge6 = [n for n in ra.index if n >= 6 and n in no.index]
        better6 = all(ra[n] < no[n] for n in ge6) if ge6 else False
        out.append(_v(e, "RA needs >= 6 images (worse than None at 4, better from 6 on)",
                      n4 and better6, ", ".join(f"n={int(n)}: RA {_f(ra[n])} / None {_f(no[n])}"
                                                for n in ra.index if n in no.index)))
    else:
        out.append(_nodata(e, "RA needs >= 6 images"))
    if len(no) > 1:
        d = no.iloc[0] - no.iloc[-1]
        out.append(_v(e, "None: NE decreases only slightly from 4 to 12 images", 0 <= d < 2.0,
                      f"{_f(no.iloc[0])} -> {_f(no.iloc[-1])}"))
    rel = {}
    for f in ("Th", "Th-Hi-Re-Sh", "NL-Sh"):
        m = s[f]
        c = [n for n in m.index if n in no.index]
        if len(c) > 1:
            rel[f] = ((no[c[0]] - m[c[0]]) / no[c[0]], (no[c[-1]] - m[c[-1]]) / no[c[-1]])
    if rel:
        out.append(_v(e, "The relative improvement of masks over None grows with image count",
                      all(b > a for a, b in rel.values()),
                      ", ".join(f"{k}: {100 * a:.0f} % -> {100 * b:.0f} %"
                                for k, (a, b) in rel.items())))
    sl = {f: _slope(v) for f, v in s.items() if len(v) > 1}
    if "RA" in sl:
        out.append(_lowest(e, "RA improves the most with increasing image count (steepest fall)",
                           sl, "RA", margin=0.05, unit="deg/image"))
    return out


def v_fig5_14(agg, rows=None):
    e = "fig5_14"
    out = []
    s0 = series(agg, "", "0")
    for nz in ("0.05", "0.1"):
        s = series(agg, "", nz)
        if 8.0 in s.index and 12.0 in s.index:
            out.append(_v(e, f"With {float(nz) * 100:g} % noise NL with 12 images is worse than "
                          f"with 8", s[12.0] > s[8.0], f"8 img {_f(s[8.0])}, 12 img {_f(s[12.0])}",
                          undecided=abs(s[12.0] - s[8.0]) < NE_MARGIN))
        else:
            out.append(_nodata(e, f"With {float(nz) * 100:g} % noise NL with 12 images is worse "
                               f"than with 8"))
    if 8.0 in s0.index and 12.0 in s0.index:
        out.append(_v(e, "Without noise NL works with 12 images (no worse than 8)",
                      s0[12.0] <= s0[8.0] + NE_MARGIN, f"8 img {_f(s0[8.0])}, 12 img "
                      f"{_f(s0[12.0])}"))
    return out


CHECKS = {name: globals()[f"v_{name}"] for name in (
    "table2_1", "table5_2", "table5_3", "table5_4", "table5_5", "table5_6", "table6_1",
    "table6_2", "fig4_3", "fig4_4", "fig4_6", "fig4_7", "fig4_9", "fig4_10", "fig5_12",
    "fig5_13", "fig5_14")}


def verdicts(experiment: str, agg: pd.DataFrame, rows: pd.DataFrame | None = None):
    """The verdict list of one experiment (never raises: a failing check is INCONCLUSIVE)."""
    fn = CHECKS.get(experiment)
    if fn is None:
        return []
    try:
        return [v for v in fn(agg, rows) if v is not None]
    except Exception as exc:  # noqa: BLE001 - a broken check must not break the report
        return [Verdict(experiment, "(verdict computation)", INCONCLUSIVE,
                        f"check failed: {type(exc).__name__}: {exc}")]
