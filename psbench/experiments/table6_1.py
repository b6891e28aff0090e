"""Table 6.1: IE of the WPS weights on real image folders, % of 2Z PS."""
from __future__ import annotations

import pandas as pd

from psbench.report.aggregates import long_frame, labels, data_name, weight_row, lookup
from psbench.report.verdicts import verdict, nodata, lowest, part_values, num

TITLE = "Table 6.1: IE of WPS weights on real images (% of 2Z PS)"
AVERAGES = ("IE of each WPS weight (Eq. 2.30, the ring-weighted IE stored as "
            "ie_weighted) as % of ordinary PS's IE (Eq. 2.29, ie_l2) on the same 2Z "
            "layout and folder; 'overall' pools the IE of all folders (sum / sum), like "
            "the thesis's Overall column. psbench's folders (sim rig, DiLiGenT cat/bear)"
            " differ from the thesis's objects, so only the overall column and the "
            "orderings are compared.")
NOTES = ("psbench's real folders are not the thesis's objects: three simulated-rig "
         "captures (penny, mozart, spheres; TS; psbench-capture rig=sim + "
         "psbench-calibrate all; made deterministically under <results>/simrig the first"
         " time the experiment runs) and the DiLiGenT cat and bear. DiLiGenT's lights "
         "reach only ~43 deg zenith, so its '60 deg' ring is its outermost lights; a "
         "missing folder makes its runs fail (listed on the page). Rows stored before "
         "the harness recorded ie_weighted (Eq. 2.30) fall back to Eq. 2.29 for WPS "
         "(part 'info' says which), under which WPS cannot beat PS's least-squares "
         "residual; the 'WPS reduces IE' verdicts are then INCONCLUSIVE.")
GATED = False

#: the thesis's real objects (columns; psbench's folders differ, see NOTES)
OBJECTS = ("bearing_ball", "coin", "horses", "metal_toy_face", "plastic_toy_face", "overall")


def _rows(rows):
    return {r[0]: dict(zip(OBJECTS, r[1:])) for r in rows}


# IE as % of 2Z PS (None) per object of the thesis's rig.
THESIS = {
    "30x4+60x4": _rows([
        ("None", 100.0, 100.0, 100.0, 100.0, 100.0, 100.0),
        ("e", 49.8, 55.5, 38.8, 61.1, 54.4, 50.5),
        ("eZsource", 49.5, 55.7, 38.6, 65.1, 58.9, 51.9),
        ("eZsurface", 53.3, 52.9, 41.3, 68.3, 72.9, 56.0),
        ("eZsourceZsurface", 52.2, 52.3, 40.1, 70.1, 76.7, 56.3),
    ]),
    "30x8+60x8": _rows([
        ("None", 100.0, 100.0, 100.0, 100.0, 100.0, 100.0),
        ("e", 64.7, 92.0, 62.0, 70.6, 59.9, 68.4),
        ("eZsource", 63.6, 90.2, 60.5, 77.6, 65.9, 70.0),
        ("eZsurface", 68.5, 82.7, 62.3, 81.1, 87.9, 75.0),
        ("eZsourceZsurface", 67.2, 80.5, 60.5, 86.2, 94.0, 76.1),
    ]),
}


def cell_kind(part, column):
    return "percent"


PART_TITLES = {"30x4+60x4": "IE as % of 2Z PS, 30x4+60x4 (8 images)",
               "30x8+60x8": "IE as % of 2Z PS, 30x8+60x8 (16 images)",
               "info": "IE definition of the WPS rows"}
TABLE_AXES = {"info": ("", ""), "*": ("WPS weight (None = 2Z PS)",
                    "the compared overall column, psbench's folders, the thesis's objects")}


def cell_unit(part, column):
    return "" if part == "info" else "% of 2Z PS"


def _records(df):
    """IE of each weight as % of 2Z PS. WPS rows use ``ie_weighted`` (Eq. 2.30: ring IEs
    of each ring's own solution, weighted) when the store has it, PS rows ``ie_l2``
    (Eq. 2.29); both are L2 norms averaged over images, so the ratio is the thesis's.
    Part ``info`` records whether Eq. 2.30 was available (1) or Eq. 2.29 was used (0)."""
    recs = []
    if df.empty:
        return recs
    d = df.copy()
    d["_row"] = labels(d, weight_row)
    d["_obj"] = [data_name(x) for x in d.get("data", [None] * len(d))]
    ie = "_ie"
    wps = d["_row"] != "None"
    has_w = "ie_weighted" in d and d.loc[wps, "ie_weighted"].notna().all() and wps.any()
    d[ie] = pd.to_numeric(d["ie_l2"], errors="coerce")
    if has_w:
        d.loc[wps, ie] = pd.to_numeric(d.loc[wps, "ie_weighted"], errors="coerce")
    recs.append(("info", "WPS IE is Eq. 2.30 (1) or Eq. 2.29 (0)", "value",
                 1.0 if has_w else 0.0, int(wps.sum())))
    for lay, g in d.groupby("lights"):
        base = g[g["_row"] == "None"].groupby("_obj")[ie].mean()
        for w, gw in g.groupby("_row"):
            m = gw.groupby("_obj")[ie].mean()
            common = [o for o in m.index if o in base.index and base[o] > 0]
            for o in common:
                recs.append((str(lay), w, o, 100.0 * m[o] / base[o], int((gw["_obj"] == o).sum())))
            if common:
                recs.append((str(lay), w, "overall",
                             100.0 * float(m[common].sum()) / float(base[common].sum()),
                             int(len(gw))))
    return recs


def aggregate(rows):
    """The long-format aggregate of the experiment's ok rows."""
    return long_frame(_records(rows))


def verdicts(agg, rows=None):
    """One verdict per conclusion the thesis draws from this experiment."""
    out = []
    if agg is None or agg.empty:
        return [nodata("WPS reduces IE w.r.t. PS for every weight"),
                nodata("e weights give the lowest IE on real images")]
    eq230 = lookup(agg, "info", "WPS IE is Eq. 2.30 (1) or Eq. 2.29 (0)", "value") == 1.0
    for lay in sorted(p for p in agg["part"].unique() if p != "info"):
        ov = {r: v for r, v in part_values(agg, lay, "overall").items()}
        wps = {k: v for k, v in ov.items() if k != "None"}
        if wps and eq230:
            out.append(verdict(f"WPS reduces IE w.r.t. 2Z PS for every weight ({lay})",
                               all(v < 100 for v in wps.values()),
                               ", ".join(f"{k} {num(v, 1)} %" for k, v in wps.items())
                               + " (Eq. 2.30 IE of WPS vs Eq. 2.29 IE of PS)"))
            out.append(lowest(f"e weights give the lowest IE on real images ({lay})", wps,
                              "e", margin=0.5, unit="%"))
        elif wps:
            # The store's ie_* of a WPS row is Eq. 2.29 over all images with the fused
            # normals; the least-squares PS solution minimizes exactly that residual, so
            # no WPS row can be below 100 % under it. The thesis's Table 6.1 uses the
            # weighted per-ring IE of Eq. 2.30. Below 100 % would decide the claim; at or
            # above 100 % it cannot be decided with this IE definition.
            below = all(v < 100 for v in wps.values())
            out.append(verdict(f"WPS reduces IE w.r.t. 2Z PS for every weight ({lay})", below,
                               ", ".join(f"{k} {num(v, 1)} %" for k, v in wps.items())
                               + ("" if below else " -- stored IE is Eq. 2.29 (fused normals, all "
                                  "images), which cannot fall below the PS least-squares residual; "
                                  "the thesis uses the weighted per-ring IE of Eq. 2.30"),
                               undecided=not below))
            out.append(lowest(f"e weights give the lowest IE on real images ({lay})", wps,
                              "e", margin=0.5, unit="%"))
    return out or [nodata("WPS reduces IE w.r.t. PS for every weight")]


def prepare(root, scale):
    """Make the simulated-rig captures the grid reads, under ``<root>/simrig``, when they
    are missing (deterministic; see :mod:`psbench.experiments._simrig`)."""
    from ._simrig import prepare as make

    make(root, scale)
