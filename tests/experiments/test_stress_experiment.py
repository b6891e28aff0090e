"""The stress experiment: departure labels, aggregate and verdicts on synthetic rows."""
from __future__ import annotations

import json

import pandas as pd

from psbench.experiments import stress as E
from psbench.harness.grid import expand


def test_every_departure_of_the_grid_has_its_own_label():
    runs = expand("stress", "ci")
    labels = {E.departure(r) for r in runs}
    assert len(labels) == 19                     # 15 alone + 4 combined
    assert "none (TS, the solvers' model)" in labels
    assert "GGX a=0.1 F0=0.04" in labels and "2 bounces" in labels and "8-bit" in labels
    per = pd.Series([E.departure(r) for r in runs]).value_counts()
    assert (per == len(E.SOLVERS)).all()         # every solver under every departure
    assert len(expand("stress", "ci")) < 300     # ci: one scene set per departure


def _rows(robust_gap):
    recs = []
    for dep in ({}, {"gamma": 2.2}):
        for surf in ("sombrero", "cup"):
            vals = {"None": 8.0, "trim": 6.0, "robust": 2.0, "tsfit": 1.5}
            if dep and surf == "cup":
                vals["robust"] = 6.0 + robust_gap
                vals["tsfit"] = 9.0
            for lab, v in vals.items():
                meth, mask = ("ps", lab) if lab == "None" else (lab, "None")
                recs.append(dict(model="ts", render=json.dumps(dep) if dep else None,
                                 bounces=None, quantize=None, surface=surf, lights="30x8+60x8",
                                 noise=0.02, method=meth, mask=mask, th_scope="image",
                                 thresholds=None, ne_mean=v, t_solve=0.01))
    return pd.DataFrame(recs)


def test_lost_cells_and_verdicts():
    agg = E.aggregate(_rows(robust_gap=0.5))
    lost = agg[agg["part"] == "lost"]
    assert set(lost["row"]) == {"gamma 2.2 | cup | 30x8+60x8 | 0.02"}
    d = agg[(agg["part"] == "default") & (agg["row"] == "gamma 2.2")]
    assert float(d.loc[d["column"] == "cells lost", "value"].iloc[0]) == 1
    v = {x.claim: x.status for x in E.verdicts(agg)}
    every = [c for c in v if "in every cell" in c and "tsfit" not in c][0]
    assert v[every] == "NOT SUPPORTED"
    assert v[[c for c in v if "tsfit" in c][0]] == "NOT SUPPORTED"
    avg = [c for c in v if "best of least squares and trim" in c and "average" in c][0]
    assert v[avg] == "SUPPORTED"       # (2 + 2 + 2 + 6.5) / 4 < 6
    ok = {x.claim: x.status for x in E.verdicts(E.aggregate(_rows(robust_gap=0.2)))}
    assert ok[every] == "SUPPORTED"


def test_empty_is_inconclusive():
    assert all(x.status == "INCONCLUSIVE" for x in E.verdicts(E.aggregate(pd.DataFrame())))
