"""Table 5.3's part "model": tsfit beside the masks, per noise level (issue 16)."""
from __future__ import annotations

import pandas as pd
import pytest

from psbench.experiments import table5_3
from psbench.report import verdicts as V


def _rows(ne_by_method):
    """One surface, layouts 45x4 (masks only) and 45x8; ``{(method, mask): {noise: ne}}``."""
    rows = []
    for (method, mask), per_noise in ne_by_method.items():
        for noise, ne in per_noise.items():
            for lights, k in (("45x4", 4), ("45x8", 8)):
                if method == "tsfit" and k == 4:
                    continue  # tsfit needs >= 5 images
                rows.append(dict(seed=0, surface="s", lights=lights, n_images=k, noise=noise,
                                 mask=mask, method=method, ne_mean=ne + (k == 4),
                                 t_solve=0.1, qf_hi=0.5, qf_sh=0.5, qf_total=0.5))
    return pd.DataFrame(rows)


def _claims(agg, rows):
    return {v.claim: v for v in table5_3.verdicts(agg, rows)}


def test_model_part_per_noise_level_and_thesis_parts_untouched():
    rows = _rows({("ps", "None"): {0.0: 10.0, 0.1: 12.0, 0.2: 16.0},
                  ("ps", "Th"): {0.0: 5.0, 0.1: 11.0, 0.2: 18.0},
                  ("tsfit", "None"): {0.0: 1.0, 0.1: 10.95, 0.2: 17.0}})
    agg = table5_3.aggregate(rows)
    cell = lambda p, r, c: agg[(agg.part == p) & (agg.row == r) & (agg.column == c)]  # noqa: E731
    # the thesis part's "None" row averages the ps runs only (45x4 adds 1 deg)
    assert cell("all", "None", "ne")["value"].iloc[0] == pytest.approx((10.5 + 12.5 + 16.5) / 3)
    assert cell("all", "tsfit", "ne").empty
    # part "model": the layouts tsfit has (45x8), per noise level
    assert cell("model", "None", "ne_10")["value"].iloc[0] == pytest.approx(12.0)
    assert cell("model", "tsfit", "ne_20")["value"].iloc[0] == pytest.approx(17.0)
    assert cell("model", "Th", "ne_0")["n"].iloc[0] == 1
    assert table5_3.cell_kind("model", "ne_10") == "ne"
    v = _claims(agg, rows)
    at = lambda p: v[f"modelling the highlight "  # noqa: E731
                     f"(tsfit) beats masking it (the best mask) at {p} % noise"]
    assert not any(at(p).thesis for p in (0, 10, 20))   # psbench's question: not counted
    assert at(0).status == V.SUPPORTED and "next Th 5" in at(0).detail
    assert at(10).status == V.INCONCLUSIVE       # 0.05 deg ahead of Th: below the margin
    assert at(20).status == V.NOT_SUPPORTED and "best None 16" in at(20).detail


def test_without_tsfit_runs_the_model_verdicts_are_inconclusive():
    rows = _rows({("ps", "None"): {0.0: 10.0}, ("ps", "Th"): {0.0: 5.0}})
    rows = rows.drop(columns="method")           # rows stored before the method column
    agg = table5_3.aggregate(rows)
    assert (agg.part != "model").all()
    v = [x for x in table5_3.verdicts(agg, rows) if "modelling the highlight" in x.claim]
    assert len(v) == 3 and all(x.status == V.INCONCLUSIVE for x in v)
