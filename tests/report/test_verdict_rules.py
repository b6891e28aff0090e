"""The shared verdict rules of psbench.report.verdicts on constructed numbers."""
from __future__ import annotations

import pandas as pd
import pytest

from psbench.report import verdicts as V


def test_decide_uses_margin_both_ways():
    assert V.decide("c", 0.3, "d").status == V.SUPPORTED
    assert V.decide("c", -0.3, "d").status == V.NOT_SUPPORTED
    assert V.decide("c", 0.05, "d").status == V.INCONCLUSIVE
    assert V.decide("c", float("nan"), "d").status == V.INCONCLUSIVE
    assert "gap 0.30 deg, margin 0.10" in V.decide("c", 0.3, "d").detail


def test_margin_no_tighter_than_the_thesis_and_not_below_the_spread():
    assert V.margin_for(0.1) == 0.1
    assert V.margin_for(0.1, thesis_gap=0.02) == pytest.approx(0.02)   # thesis's own evidence
    assert V.margin_for(0.1, thesis_gap=1.5) == 0.1
    assert V.margin_for(0.1, thesis_gap=0.02, spread_=0.3) == 0.3
    # a 0.05 gap: decided when the thesis decided on 0.02, not when it is below the
    # seed-to-seed spread of that gap
    assert V.decide("c", 0.05, "d", thesis_gap=0.02).status == V.SUPPORTED
    v = V.decide("c", 0.05, "d", thesis_gap=0.02, seed_gaps=[0.2, -0.1, 0.05])
    assert v.status == V.INCONCLUSIVE and "spread 0.30" in v.detail and "3 seeds" in v.detail
    assert "1 seed" in V.decide("c", 0.05, "d", seed_gaps=[0.05]).detail


def test_lowest_symmetric_with_thesis_gap_and_seeds():
    vals = {"a": 1.0, "b": 1.05, "c": 2.0}
    assert V.lowest("c", vals, "a").status == V.INCONCLUSIVE            # lead 0.05 < 0.1
    assert V.lowest("c", vals, "a", thesis={"a": 3.0, "b": 3.01}).status == V.SUPPORTED
    assert V.lowest("c", vals, "b").status == V.INCONCLUSIVE
    assert V.lowest("c", vals, "c").status == V.NOT_SUPPORTED
    seeds = {0: {"a": 1.0, "b": 1.2, "c": 2}, 1: {"a": 1.1, "b": 1.0, "c": 2},
             2: {"a": 0.9, "b": 0.95, "c": 2}}
    v = V.lowest("c", vals, "a", thesis={"a": 3.0, "b": 3.01}, seeds=seeds)
    assert v.status == V.INCONCLUSIVE        # lead 0.05 < spread of the lead (0.3)
    assert V.lowest("c", {"x": 0.5, "y": 0.3}, "x", margin=0.01, highest=True).status == \
        V.SUPPORTED
    assert V.lowest("c", {}, "a").status == V.INCONCLUSIVE


def test_ranked_exact_and_within():
    vals = {"p": 1.0, "q": 1.5, "r": 2.0, "s": 2.05}
    assert V.ranked("c", vals, "q", 2).status == V.SUPPORTED           # 0.5 both sides
    assert V.ranked("c", vals, "r", 2).status == V.NOT_SUPPORTED       # ranks 3rd
    assert V.ranked("c", vals, "r", 3).status == V.INCONCLUSIVE        # 0.05 from 4th
    assert V.ranked("c", vals, "r", 3, exact=False).status == V.INCONCLUSIVE
    assert V.ranked("c", vals, "q", 3, exact=False).status == V.SUPPORTED
    assert V.ranked("c", vals, "s", 2, exact=False).status == V.NOT_SUPPORTED


def test_every_and_all_hold():
    s, n, i = (V.Verdict("", x, st, "") for x, st in
               (("a", V.SUPPORTED), ("b", V.NOT_SUPPORTED), ("c", V.INCONCLUSIVE)))
    assert V.every("x", [s, s]).status == V.SUPPORTED
    assert V.every("x", [s, i]).status == V.INCONCLUSIVE
    assert V.every("x", [s, i, n]).status == V.NOT_SUPPORTED
    assert V.every("x", []).status == V.INCONCLUSIVE
    assert V.all_hold("x", {"t1": s, "t2": s}).status == V.SUPPORTED
    assert V.all_hold("x", {"t1": n, "t2": n}).status == V.NOT_SUPPORTED
    assert V.all_hold("x", {"t1": s, "t2": n}).status == V.INCONCLUSIVE
    v = V.all_hold("x", {"t1": s, "t2": None}, quote="line 1")
    assert v.status == V.INCONCLUSIVE and "t2: no data" in v.detail and v.quote == "line 1"


def test_by_seed_common_design_and_shared_rows():
    rows = pd.DataFrame({
        "seed": [0, 0, 0, 1, 1, 2, 2],
        "mask": ["A", "A", "B", "A", "B", "A", "B"],
        "noise": [0.0, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1],
        "weight": [None, float("nan"), None, None, float("nan"), None, None],   # missing
        "ne_mean": [1.0, 2.0, 3.0, 2.2, 3.3, 1.8, 2.7]})

    def agg(r):
        return r.groupby("mask")["ne_mean"].mean()
    per = V.by_seed(rows, agg, shared=rows["noise"] == 0)
    assert set(per) == {0, 1, 2}
    # the noise-free A run counts for every seed
    assert per[1]["A"] == pytest.approx((1.0 + 2.2) / 2) and per[2]["B"] == pytest.approx(2.7)
    # without the shared mark, the noise-free run exists for seed 0 only: left out
    assert V.by_seed(rows, agg)[0]["A"] == pytest.approx(2.0)
    assert V.by_seed(rows[rows["seed"] == 0], agg) == {}


def test_verdict_keeps_its_thesis_quote():
    v = V.quoted(V.verdict("c", True, "d"), "line 9: text")
    assert v.quote == "line 9: text" and v.as_dict()["quote"] == "line 9: text"
