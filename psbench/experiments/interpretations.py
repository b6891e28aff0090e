"""Claims by interpretation: every thesis verdict that rests on an ambiguous reading of the
text, re-decided under each documented alternative reading.

Where the thesis is ambiguous psbench's literal reading is the default; this experiment
runs the claims that depend on such a reading under the default and under each
alternative, and decides each cell with the verdict rules of the experiment the claim
belongs to (its module's ``aggregate`` and ``verdicts`` on the rows of that reading). Its
page is one matrix, claim x interpretation -> SUPPORTED / NOT SUPPORTED / INCONCLUSIVE
(the numbers behind each cell are the verdict details), and one sentence per claim
saying which readings it needs.

The runs are ``kind=analysis`` runs of :mod:`psbench.analysis` functions, whose ``args``
carry the render options the run parameters do not have yet (the Torrance-Sparrow lobe
width ``m``, the highlight ground truths, the Di clamping):

- :func:`~psbench.analysis.mask_scores` for the Table 5.3 claims: one run per scene,
  every mask solved once and scored under three highlight ground truths, the Th masks
  also under the other Th range scopes;
- :func:`~psbench.analysis.wps_table` for Tables 5.5 / 5.6 (and Fig. 5.22's Di claim);
- :func:`~psbench.analysis.ne_vs_source_zenith` for Fig. 4.4;
- :func:`~psbench.analysis.ie_decomposition` for Fig. 4.10.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from psbench.report.aggregates import long_frame, parse_json
from psbench.report.verdicts import (INCONCLUSIVE, NOT_SUPPORTED, SUPPORTED, Verdict, every,
                                     nodata)

IN_TOTALS = False   # re-decides other pages' claims: listed, not counted in the report totals
TITLE = "Claims by interpretation: thesis claim x reading of the text"
AVERAGES = ("Each cell re-decides one thesis claim with the rules of its own experiment "
            "(table5_3, table5_5, table5_6, fig4_4, fig4_10) on the runs of one reading; "
            "the reduced design (image size, seeds) is stated in the grid. Matrix values: "
            "1 SUPPORTED, -1 NOT SUPPORTED, 0 INCONCLUSIVE.")
NOTES = ("A reduced design, to fit the reproduction's time budget: 128 x 128 (full scale), "
         "one seed (no seed-to-seed spread: ranking claims are decided by their margins "
         "only), and the Table 5.3 claims on 45x4 and 45x8 (Table 5.3's 'all light "
         "sources' averages 45x4, 45x6, 45x8 and 45x12). The 'literal' column is the "
         "reference for the other readings on the same design, not a substitute for the "
         "full-size pages, whose verdicts it need not match.")
GATED = False
THESIS = {}

#: the readings (columns); "literal" is psbench's default
INTERPRETATIONS = {
    "literal": "psbench's reading: TS m = 2 (radians), highlight truth cone 12 deg, Th "
               "ranges per whole image, unclamped Di, semisphere on its plane, noise "
               "0/10/20 %",
    "TS m=4": "Torrance-Sparrow lobe width m = 4 instead of 2 (a narrower lobe)",
    "truth range0.1": "highlight ground truth: specular term > 0.1 x image range "
                      "(psbench's earlier default)",
    "truth range0.5": "highlight ground truth: specular term > 0.5 x image range",
    "Th scope object": "Th bounds from the range over the object mask",
    "Th scope robust": "Th bounds from the 1st-99th percentile over the object",
    "Th scope pixel": "Th bounds relative to each pixel's brightest observation",
    "Di clamped": "Di images with attached shadows clamped to 0 (s.n <= 0 -> 0)",
    "semisphere disc": "semisphere without its ground plane (object = the disc)",
    "noise 0/2.5/5 %": "noise levels 0, 2.5, 5 % instead of 0, 10, 20 %",
}
#: which experiment a claim comes from, its claim text there, the readings it depends on
CLAIMS = {
    "T5.3 lowest": ("table5_3", "Th-Hi-Re-Sh has the lowest NE (all light sources)"),
    "T5.3 within 1 deg": ("table5_3", "Th alone is within 1 deg of Th-Hi-Re-Sh"),
    "T5.3 best single": ("table5_3", "Th is the best single mask"),
    "T5.3 xNL": ("table5_3", "xNL reduces NE w.r.t. None"),
    "T5.3 NL-Re": ("table5_3", "With 4 lights, Barsky's NL-Re performs (slightly) best "
                               "among the masking methods"),
    "T5.3 CJ": ("table5_3", "With 4 lights CJ is worse than the other masking methods "
                            "(NL-Re, Th, NL-Re-Sh)"),
    "T5.3 RA 4": ("table5_3", "RA with 4 lights is worse than None"),
    "T5.3 QF": ("table5_3", "Th has the highest total QF"),
    "T5.5 2Z": ("table5_5", "2Z beats 1Z for n_i > 4 with highlights and shadows "
                            "(ordinary PS)"),
    "T5.5 30 %": ("table5_5", "eZsourceZsurface improves on 1Z by more than 30 % at every "
                              "n_i"),
    "T5.5 best weight": ("table5_5", "eZsourceZsurface is the best weight (lowest NE "
                                     "averaged over n_i)"),
    "F5.22 Di": ("table5_5", "Diffuse images: 1Z NE is always below 2Z (Fig. 5.22)"),
    "T5.6 binary": ("table5_6", "Binary beats weighted fusion on NE (mean of the "
                                "sombreros)"),
    "F4.4 45 deg": ("fig4_4", "Z_source = 45 deg is optimal for diffuse images at every "
                              "n_i"),
    "F4.10 peak": ("fig4_10", "highlight IE peaks near Z_surface = Z_source/2"),
}
#: readings that can change each source experiment's claims
APPLIES = {
    "table5_3": ("literal", "TS m=4", "truth range0.1", "truth range0.5", "Th scope object",
                 "Th scope robust", "Th scope pixel", "semisphere disc", "noise 0/2.5/5 %"),
    "table5_5": ("literal", "TS m=4", "Di clamped"),
    "table5_6": ("literal", "TS m=4"),
    "fig4_4": ("literal", "Di clamped"),
    "fig4_10": ("literal", "TS m=4"),
}
#: the ground truth / Th scope / noise levels of the literal reading
_LITERAL = dict(truth="cone12", th_scope="image", noise=(0.0, 0.1, 0.2))
_CODE = {SUPPORTED: 1.0, NOT_SUPPORTED: -1.0, INCONCLUSIVE: 0.0}
_STATUS = {v: k for k, v in _CODE.items()}


def _args(r):
    a = parse_json(r.get("args"))
    return a if isinstance(a, dict) else {}


def _m(args):
    """TS lobe width of a run (``render_options.m``, or ``m`` of ie_decomposition)."""
    return float((args.get("render_options") or {}).get("m", args.get("m", 2.0)))


def _frames(rows):
    """The runs' payloads as one frame per analysis function, each payload row carrying
    its run's parameters (``surface, lights, noise, seed`` where the payload has none)
    and reading (``m``: TS lobe width, ``img``: image kind). ie_decomposition runs stay
    one row per run (``zenith``, ``m``, ``payload``), as Fig. 4.10's aggregate reads
    them."""
    out = {}
    for _, r in rows.iterrows():
        pl = parse_json(r.get("payload"))
        if not isinstance(pl, dict) or not pl:
            continue
        a = _args(r)
        if r.get("analysis") == "ie_decomposition":
            f = pd.DataFrame([{"zenith": r.get("zenith"), "payload": r.get("payload")}])
        else:
            f = pd.DataFrame(pl)
            for k in ("surface", "lights", "noise", "seed"):
                if k not in f:
                    f[k] = r.get(k)
        f["m"] = _m(a)
        f["img"] = a.get("kind") or (a.get("kinds") or [None])[0]
        out.setdefault(r.get("analysis"), []).append(f)
    return {k: pd.concat(v, ignore_index=True) for k, v in out.items()}


def _sel(f, *, m=2.0, truth="cone12", scope="image", disc=False, noise=_LITERAL["noise"]):
    """Rows of one reading of the Table 5.3 runs (``scope`` None: any Th scope)."""
    keep = (f["m"] == m) & (f["truth"] == truth) & f["noise"].isin(noise)
    keep &= (f["surface"] == "semisphere_disc") if disc else (f["surface"] != "semisphere_disc")
    if scope is not None:
        keep &= f["th_scope"] == scope
    return f[keep]


def _t53_rows(f, reading):
    if f is None or f.empty:
        return None
    d = _sel(f)
    if reading == "TS m=4":
        d = _sel(f, m=4.0)
    elif reading.startswith("truth "):
        d = _sel(f, truth=reading[len("truth "):])
    elif reading.startswith("Th scope "):
        alt = _sel(f, scope=reading[len("Th scope "):])
        if alt.empty:
            return None
        th = d["mask"].astype(str).str.split("-").apply(lambda t: "Th" in t)
        d = pd.concat([d[~th], alt])
    elif reading == "semisphere disc":
        disc = _sel(f, disc=True)
        if disc.empty:
            return None
        d = pd.concat([d[d["surface"] != "semisphere"], disc.assign(surface="semisphere")])
    elif reading == "noise 0/2.5/5 %":
        d = _sel(f, noise=(0.0, 0.025, 0.05))
    if d.empty:
        return None
    return d.assign(kind="solve", model="ts", shadows=True, method="ps")


def _wps_rows(f, reading, source):
    if f is None or f.empty:
        return None
    m = 4.0 if reading == "TS m=4" else 2.0
    hs = f[(f["m"] == m) & (f["img"].fillna("Hi-Sh") == "Hi-Sh")]
    di = f[f["img"] == ("Di-clamped" if reading == "Di clamped" else "Di")]
    if source == "table5_6":
        d = hs[(hs["weight"] == "eZsourceZsurface") & (hs["count"] == 16) & (hs["source"] == "2Z")]
        return d.assign(ne_mean=d["ne"], method="wps") if len(d) else None
    d = pd.concat([hs[~hs["binary"].astype(bool) | (hs["weight"] == "None")].assign(
        model="ts", shadows=True), di.assign(model="lambert", shadows=False)])
    if d.empty:
        return None
    return d.assign(ne_mean=d["ne"], n_images=d["count"],
                    method=np.where(d["weight"] == "None", "ps", "wps"))


def _f44_rows(f, reading):
    if f is None or f.empty:
        return None
    d = f[f["kind"] == ("Di-clamped" if reading == "Di clamped" else "Di")]
    return d.assign(ne_mean=d["ne"], n_images=d["count"]) if len(d) else None


def _f410_rows(f, reading):
    if f is None or f.empty:
        return None
    d = f[f["m"] == (4.0 if reading == "TS m=4" else 2.0)].drop_duplicates(subset=["zenith"])
    return d[["zenith", "payload"]] if len(d) else None


def _source_rows(frames, source, reading):
    if source == "table5_3":
        return _t53_rows(frames.get("mask_scores"), reading)
    if source in ("table5_5", "table5_6"):
        return _wps_rows(frames.get("wps_table"), reading, source)
    if source == "fig4_4":
        return _f44_rows(frames.get("ne_vs_source_zenith"), reading)
    return _f410_rows(frames.get("ie_decomposition"), reading)


def _verdicts(source, rows):
    """The source experiment's verdicts on the rows of one reading (None: no rows)."""
    from psbench.report.tables import experiment_module

    mod = experiment_module(source)
    if rows is None or mod is None:
        return None
    rows = rows.reset_index(drop=True)
    return mod.verdicts(mod.aggregate(rows), rows)


def _pick(vs, source, claim):
    if vs is None:
        return None
    if source == "fig4_10":   # one verdict per source zenith: all must hold
        return every(claim, [v for v in vs if "highlight IE peaks" in v.claim])
    return next((v for v in vs if v.claim == claim), None)


_MEMO = {}


def matrix(rows) -> list:
    """``[(claim id, reading, Verdict or None)]`` for every claim and applicable reading
    (each source experiment's verdicts computed once per reading)."""
    key = tuple(rows["run_id"]) if rows is not None and "run_id" in rows else None
    if key is not None and key in _MEMO:
        return _MEMO[key]
    frames = _frames(rows) if rows is not None and len(rows) else {}
    decided = {}
    for source, readings in APPLIES.items():
        for reading in readings:
            try:
                decided[source, reading] = _verdicts(source, _source_rows(frames, source,
                                                                          reading))
            except Exception as exc:  # noqa: BLE001 - one broken cell must not hide the rest
                decided[source, reading] = [Verdict("", claim, INCONCLUSIVE, "check failed: "
                                                    f"{type(exc).__name__}: {exc}")
                                            for s, claim in CLAIMS.values() if s == source]
    out = [(cid, reading, _pick(decided[source, reading], source, claim))
           for cid, (source, claim) in CLAIMS.items() for reading in APPLIES[source]]
    if key is not None:
        _MEMO.clear()
        _MEMO[key] = out
    return out


def aggregate(rows):
    """Part ``matrix``: row = claim id, column = reading, value = status code (1
    SUPPORTED, -1 NOT SUPPORTED, 0 INCONCLUSIVE); cells without data are left out."""
    return long_frame([("matrix", cid, reading, _CODE[v.status], 1)
                       for cid, reading, v in matrix(rows) if v is not None
                       and not v.detail.startswith("no data")])


def needs(cells: dict) -> str:
    """The sentence saying what a claim needs to hold, from ``{reading: status}``
    (None: no data for that reading)."""
    lit = cells.get("literal")
    if lit is None:
        return "no data under the literal reading"
    alt = {r: s for r, s in cells.items() if r != "literal" and s is not None}
    if all(s == lit for s in alt.values()):
        return (f"{lit} under the literal reading and under every alternative run "
                f"({', '.join(alt) or 'none'}): it does not depend on these readings.")
    by = {st: [r for r, s in cells.items() if s == st]
          for st in (SUPPORTED, NOT_SUPPORTED, INCONCLUSIVE)}
    text = "; ".join(f"{st} under {', '.join(rs)}" for st, rs in by.items() if rs)
    ok_ = by[SUPPORTED]
    if not ok_:
        return f"{text}. It holds under none of the readings run."
    if lit == SUPPORTED:
        return f"{text}. It holds under the literal reading but not under every alternative."
    return f"{text}. It needs the reading{'s' if len(ok_) > 1 else ''} {', '.join(ok_)}."


def verdicts(agg, rows=None):
    """One verdict per matrix cell (claim [reading], with the numbers of its source
    verdict) and one per claim with the sentence saying which readings it needs."""
    cells = matrix(rows) if rows is not None and len(rows) else [
        (r, c, Verdict("", r, _STATUS.get(v, INCONCLUSIVE), "status only (no rows)"))
        for r, c, v in (agg[["row", "column", "value"]].itertuples(index=False)
                        if agg is not None and not agg.empty else [])]
    if not cells:
        return [nodata("claims by interpretation")]
    out, by_claim = [], {}
    for cid, reading, v in cells:
        v = v if v is not None else nodata(CLAIMS.get(cid, (None, cid))[1])
        by_claim.setdefault(cid, {})[reading] = None if v.detail.startswith("no data") \
            else v.status
        out.append(dataclasses.replace(v, experiment="", claim=f"{cid} [{reading}]: "
                                       f"{CLAIMS.get(cid, (None, cid))[1]}"))
    for cid, st in by_claim.items():
        lit = st.get("literal")
        out.append(Verdict("", f"{cid}: what it needs", lit or INCONCLUSIVE, needs(st)))
    return out


def figures(agg):
    """The matrix as a coloured table (green SUPPORTED, red NOT SUPPORTED, grey
    INCONCLUSIVE, blank: the reading does not apply or has no data)."""
    from psbench.report.figures import plt

    if agg is None or agg.empty:
        return []
    m = agg[agg["part"] == "matrix"]
    claims = [c for c in CLAIMS if c in set(m["row"])]
    readings = [r for r in INTERPRETATIONS if r in set(m["column"])]
    fig, ax = plt.subplots(figsize=(1.1 + 0.75 * len(readings), 0.9 + 0.32 * len(claims)))
    colour = {1.0: "#7fc97f", -1.0: "#f0827d", 0.0: "#d0d0d0"}
    text = {1.0: "S", -1.0: "NS", 0.0: "I"}
    for i, c in enumerate(claims):
        for j, r in enumerate(readings):
            v = m[(m["row"] == c) & (m["column"] == r)]["value"]
            if len(v):
                x = float(v.iloc[0])
                ax.add_patch(plt.Rectangle((j, i), 1, 1, color=colour[x]))
                ax.text(j + 0.5, i + 0.5, text[x], ha="center", va="center", fontsize=7)
    ax.set_xlim(0, len(readings))
    ax.set_ylim(len(claims), 0)
    ax.set_xticks(np.arange(len(readings)) + 0.5, readings, rotation=60, ha="right",
                  fontsize=7)
    ax.set_yticks(np.arange(len(claims)) + 0.5, claims, fontsize=7)
    ax.set_title("claim x reading (S supported, NS not supported, I inconclusive)",
                 fontsize=8)
    fig.tight_layout()
    return [("interpretations", fig)]


def cell_kind(part, column):
    return "ratio"

