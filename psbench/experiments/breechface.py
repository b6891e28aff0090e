"""Real breech faces -- which reconstruction identifies the gun?

Every run of the grid is one part of :mod:`psbench.forensic.breechface_runs` (a method
label on every scan and finish, the scans themselves, the panels of one same-gun pair);
its json payload holds the per-scan rows (height error, times) and the scores of every
pair (CMC count, CCFmax). :func:`aggregate` reduces them per finish and method /
integrator with :func:`psbench.forensic.breechface.summarise`; the pair scores and the
panel pictures travel with the aggregate in ``agg.attrs`` (drawn by :func:`figures`).
"""
from __future__ import annotations

from dataclasses import replace

import pandas as pd

from psbench.report.aggregates import long_frame, parse_json
from psbench.report.verdicts import nodata, num, part_values, verdict

TITLE = "Real breech faces: identification from PS reconstructions of X3P scans"
AVERAGES = ("Every pair of the study's scans (same gun vs different guns, from guns.csv), "
            "per finish and method / integrator: ROC AUC of the CMC count and of CCFmax, "
            "separation (smallest same-gun score - largest different-gun score; > 0: one "
            "threshold separates every pair), false positives / negatives at the CMC "
            "decision threshold (>= 6 congruent cells, Song 2013), equal error rate, the "
            "median same-gun and largest different-gun CMC counts; height error = mean "
            "|difference| between the band-passed (16-500 um) reconstruction and scan over "
            "the scan's valid points (um); times per scan (render, solve, integrate, "
            "band-pass: wall seconds on a shared machine) and per pair (one CMC "
            "comparison). 'scan' is the scans themselves (the upper bound).")
NOTES = ("Real topographies (X3P) rendered by psbench's rig simulator, not photographed: "
         "the renders carry the simulator's reflectance model (Torrance-Sparrow brass / "
         "nickel presets), exposure metered on the whole frame (a scan's data cover about "
         "a third of it, so the face is exposed brighter and the 31 deg ring clips: see "
         "psbench.forensic.recipe) and camera noise, but no real optics. CMC after Song "
         "(2013) with cmcR's defaults (8 x 8 cells, 16-500 um band-pass, 20 px = 125 um, "
         "6 deg, CCF 0.5) and psbench's coarse-to-fine search (psbench.forensic.cmc). "
         "The ci scale crops every scan to the 256 x 256 window holding the most data "
         "and runs three methods on four scans: its numbers test the pipeline, "
         "not the methods. The thesis reports no numbers on real scans.")
THESIS = {}
GATED = False
COLUMNS = ("AUC CMC", "AUC CCF", "separation CMC", "separation CCF", "FP", "FN", "EER CMC",
           "EER CCF", "same-gun median CMC", "different-gun max CMC", "height error",
           "time per scan", "time per pair")
_KEYS = ("auc_cmc", "auc_ccf", "separation_cmc", "separation_ccf", "fp", "fn", "eer_cmc",
         "eer_ccf", "same_median_cmc", "diff_max_cmc", "height_error_um", "scan_s", "pair_s")
SCAN = "scan"
RECIPE = "recipe"
TABLE_AXES = {"*": ("method / integrator", "identification")}


def cell_kind(part, column):
    if column.startswith("time"):
        return "time"
    if column == "height error":
        return "ie"
    return "qf"


def cell_unit(part, column):
    return {"time": "s", "ie": "um"}.get(cell_kind(part, column), "")


def _row(method, integ):
    return method if integ in (None, "-") else f"{method} / {integ}"


def _payloads(rows):
    out = {"method": [], "scan": [], "panels": []}
    for p in rows.get("payload", pd.Series([], dtype=object)):
        d = parse_json(p)
        if isinstance(d, dict) and d.get("part") in out and not d.get("skipped"):
            out[d["part"]].append(d)
    return out


def _tables(loads):
    frames = [pd.DataFrame(d.get("scores") or []) for d in loads["method"] + loads["scan"]]
    frames = [f for f in frames if len(f)]
    scores = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    per = [r for d in loads["method"] for r in d.get("per_scan") or []]
    per = pd.DataFrame(per)
    if len(per):
        # time per scan: render + solve + integrate of one method, shared by its integrators
        per["scan_s"] = per.groupby(["finish", "scan", "method"])["scan_s"].transform("first")
    return scores, per


def aggregate(rows):
    """The long-format aggregate: one part per finish (the scans' row in each); ``attrs``
    ``scores`` (every pair) and ``panels``."""
    from psbench.forensic.breechface import summarise

    loads = _payloads(rows)
    scores, per = _tables(loads)
    recs = []
    if len(scores):
        finishes = sorted(set(scores["finish"]) - {"-"}) or ["-"]
        table = summarise(scores, per if len(per) else None)
        if len(per):
            extra = per.groupby(["finish", "method", "integrator"], sort=False)["scan_s"]
            table = table.merge(extra.mean().reset_index(), how="left",
                                on=["finish", "method", "integrator"])
        for _, r in table.iterrows():
            parts = finishes if r["finish"] == "-" else [r["finish"]]
            n = int(r["n_same"] + r["n_diff"])
            for part in parts:
                for col, key in zip(COLUMNS, _KEYS):
                    if key in r and pd.notna(r[key]):
                        recs.append((part, _row(r["method"], r["integrator"]), col,
                                     float(r[key]), n))
    agg = long_frame(recs)
    agg.attrs["scores"] = scores
    agg.attrs["panels"] = loads["panels"][-1] if loads["panels"] else None
    return agg


def _val(agg, part, row, col):
    return part_values(agg, part, col).get(row)


def verdicts(agg, rows=None):
    """psbench's questions on real scans (the thesis has none): decided per finish."""
    claims = [
        "The scans themselves separate same-gun from different-gun pairs by the CMC "
        "decision (no false positive or negative at >= 6 cells)",
        "psbench's recipe identifies as well as the scans: AUC (CMC) within 0.01 of theirs "
        "and no more false positives at the CMC threshold",
        "Least squares (None) identifies as well as the scans (AUC within 0.01)",
        "Th-Hi-Re-Sh keeps the identification of least squares on real marks (AUC not "
        "lower by more than 0.01)",
    ]
    if agg is None or agg.empty:
        return [replace(nodata(c), thesis=False) for c in claims]
    parts = sorted(set(agg["part"]))
    out = []

    def per_part(fn):
        conds, details = [], []
        for p in parts:
            c, d = fn(p)
            details.append(f"{p}: {d}")
            if c is not None:
                conds.append(c)
        return (all(conds) if conds else None), "; ".join(details)

    def upper(p):
        fp, fn = _val(agg, p, SCAN, "FP"), _val(agg, p, SCAN, "FN")
        if fp is None:
            return None, "no scan scores"
        return fp == 0 and fn == 0, f"scans FP {num(fp, 0)}, FN {num(fn, 0)}, AUC " \
                                    f"{num(_val(agg, p, SCAN, 'AUC CMC'), 3)}"
    out.append(verdict(claims[0], *per_part(upper)))

    def close(label, fp_too):
        def fn(p):
            ref = _val(agg, p, SCAN, "AUC CMC")
            rows_ = [r for r in part_values(agg, p, "AUC CMC") if r.split(" / ")[0] == label]
            if ref is None or not rows_:
                return None, "no data"
            ok_, txt = True, []
            for r in rows_:
                a = _val(agg, p, r, "AUC CMC")
                fp, fps = _val(agg, p, r, "FP"), _val(agg, p, SCAN, "FP")
                ok_ &= a >= ref - 0.01 and (not fp_too or fp <= fps)
                txt.append(f"{r} AUC {num(a, 3)} FP {num(fp, 0)}")
            return ok_, ", ".join(txt) + f" (scans AUC {num(ref, 3)}, FP " \
                                         f"{num(_val(agg, p, SCAN, 'FP'), 0)})"
        return fn
    out.append(verdict(claims[1], *per_part(close(RECIPE, True))))
    out.append(verdict(claims[2], *per_part(close("None", False))))

    def masks(p):
        a = {r: v for r, v in part_values(agg, p, "AUC CMC").items()}
        pairs = [(r, r.replace("Th-Hi-Re-Sh", "None", 1)) for r in a
                 if r.startswith("Th-Hi-Re-Sh")]
        pairs = [(m, n) for m, n in pairs if n in a]
        if not pairs:
            return None, "no data"
        return all(a[m] >= a[n] - 0.01 for m, n in pairs), ", ".join(
            f"{m} {num(a[m], 3)} vs {n} {num(a[n], 3)}" for m, n in pairs)
    out.append(verdict(claims[3], *per_part(masks)))
    return [replace(v, thesis=False) for v in out]


def figures(agg):
    """ROC curves, score distributions per method and the same-gun pair's panels."""
    from ._breechface_figures import pair_figure, roc_figure, score_figure

    figs = []
    sc = agg.attrs.get("scores")
    if sc is not None and len(sc):
        figs.append(("breechface_roc", roc_figure(sc)))
        figs.append(("breechface_scores", score_figure(sc)))
    if agg.attrs.get("panels"):
        figs.append(("breechface_pair", pair_figure(agg.attrs["panels"])))
    return figs
