"""The claims-by-interpretation experiment on a tiny design of real analysis runs."""
from __future__ import annotations

import json

import pandas as pd
import pytest

from psbench.experiments import interpretations as I
from psbench.harness.run import execute, normalize
from psbench.report import verdicts as V

MASKS = [{"mask": m} for m in ("None", "Th", "xNL", "RA", "Th-Hi-Re-Sh", "NL-Re", "NL-Re-Sh",
                               "CJ")]


def _run(**p):
    row = execute(normalize({"kind": "analysis", "size": 16, "model": "ts", "shadows": True,
                             **p}))
    assert row["status"] == "ok", row.get("error")
    return {k: v for k, v in row.items() if not k.startswith("_")}


@pytest.fixture(scope="module")
def rows():
    out = []
    for surface in ("semisphere", "sombrero"):
        for noise in (0.0, 0.1):
            for extra in ({"th_scopes": ["object"]}, {"render_options": {"m": 4}}):
                out.append(_run(analysis="mask_scores", surface=surface, lights="45x4",
                                noise=noise, args={"cases": MASKS, **extra}))
        out.append(_run(analysis="mask_scores", surface=surface, lights="45x4", noise=0.025,
                        args={"cases": MASKS, "truths": ["cone12"]}))
    out.append(_run(analysis="mask_scores", surface="semisphere_disc", lights="45x4", noise=0.1,
                    args={"cases": MASKS, "truths": ["cone12"]}))
    for extra in ({"binary": [False, True]}, {"binary": [False, True], "render_options": {"m": 4}},
                  {"kind": "Di", "weights": ["None"]},
                  {"kind": "Di-clamped", "weights": ["None"]}):
        out.append(_run(analysis="wps_table", surface="sombrero1", noise=0.05,
                        args={"counts": [8, 16], "zeniths": [30, 60], **extra}))
    for kind in ("Di", "Di-clamped"):
        out.append(_run(analysis="ne_vs_source_zenith", surface="sombrero1", noise=0.05,
                        mask="None", args={"kinds": [kind], "counts": [8],
                                           "zeniths": [30, 45, 60]}))
    for lights in ("30x8", "60x8"):
        for m in (2, 4):
            out.append(_run(analysis="ie_decomposition", surface="sombrero2", lights=lights,
                            noise=0.0, args={"by": "surface", "m": m}))
    return pd.DataFrame(out)


def test_every_claim_is_decided_under_its_readings(rows):
    cells = I.matrix(rows)
    assert {(c, r) for c, r, _ in cells} == {(c, r) for c, (src, _) in I.CLAIMS.items()
                                             for r in I.APPLIES[src]}
    got = {(c, r): v for c, r, v in cells}
    # the design has data for these cells: a verdict of the claim's own experiment
    for key in [("T5.3 NL-Re", "literal"), ("T5.3 NL-Re", "TS m=4"),
                ("T5.3 QF", "truth range0.5"), ("T5.3 lowest", "Th scope object"),
                ("T5.3 RA 4", "semisphere disc"), ("T5.3 xNL", "noise 0/2.5/5 %"),
                ("T5.6 binary", "TS m=4"), ("T5.5 2Z", "literal"), ("F5.22 Di", "Di clamped"),
                ("F4.4 45 deg", "Di clamped"), ("F4.10 peak", "TS m=4")]:
        v = got[key]
        assert v is not None and v.status in (V.SUPPORTED, V.NOT_SUPPORTED, V.INCONCLUSIVE)
        assert not v.detail.startswith("check failed"), (key, v.detail)
    # a reading changes the numbers the claim is decided on
    assert got[("T5.3 QF", "literal")].detail != got[("T5.3 QF", "truth range0.1")].detail
    assert got[("T5.6 binary", "literal")].detail != got[("T5.6 binary", "TS m=4")].detail
    assert got[("F4.4 45 deg", "literal")].detail != got[("F4.4 45 deg", "Di clamped")].detail


def test_th_scope_and_disc_readings_swap_only_their_rows(rows):
    f = I._frames(rows)["mask_scores"]
    lit = I._t53_rows(f, "literal")
    obj = I._t53_rows(f, "Th scope object")
    assert set(lit["th_scope"]) == {"image"}
    assert set(obj[obj["mask"].isin(["Th", "Th-Hi-Re-Sh"])]["th_scope"]) == {"object"}
    assert set(obj[~obj["mask"].isin(["Th", "Th-Hi-Re-Sh"])]["th_scope"]) == {"image"}
    disc = I._t53_rows(f, "semisphere disc")
    assert "semisphere_disc" not in set(disc["surface"]) and len(disc[disc["surface"] ==
                                                                     "semisphere"])
    assert set(I._t53_rows(f, "TS m=4")["m"]) == {4.0}
    assert set(I._t53_rows(f, "noise 0/2.5/5 %")["noise"]) <= {0.0, 0.025, 0.05}


def test_aggregate_verdicts_and_matrix_figure(rows):
    agg = I.aggregate(rows)
    assert set(agg["part"]) == {"matrix"} and set(agg["value"]) <= {-1.0, 0.0, 1.0}
    vs = I.verdicts(agg, rows)
    needs = [v for v in vs if v.claim.endswith("what it needs")]
    assert len(needs) == len(I.CLAIMS)
    assert all("literal" in v.detail for v in needs)
    # without rows the statuses come from the aggregate
    assert {v.status for v in I.verdicts(agg)} <= {V.SUPPORTED, V.NOT_SUPPORTED, V.INCONCLUSIVE}
    figs = I.figures(agg)
    assert figs and figs[0][0] == "interpretations"
    assert I.verdicts(I.aggregate(pd.DataFrame()), pd.DataFrame())[0].status == V.INCONCLUSIVE


def test_needs_sentence():
    s = I.needs({"literal": V.NOT_SUPPORTED, "TS m=4": V.SUPPORTED, "Th scope pixel": None,
                 "truth range0.1": V.NOT_SUPPORTED})
    assert s == ("SUPPORTED under TS m=4; NOT SUPPORTED under literal, truth range0.1. It "
                 "needs the reading TS m=4.")
    s = I.needs({"literal": V.SUPPORTED, "noise 0/2.5/5 %": V.NOT_SUPPORTED})
    assert s.endswith("holds under the literal reading but not under every alternative.")
    assert "does not depend" in I.needs({"literal": V.SUPPORTED, "TS m=4": V.SUPPORTED})
    assert I.needs({"TS m=4": V.SUPPORTED}) == "no data under the literal reading"


def test_grid_lists_every_reading():
    from psbench.harness.grid import expand, load

    ps = expand(load("interpretations"), "ci")
    # Fig. 4.4 is ordinary PS: the run parameter mask (default Th) reaches the function
    assert {p["mask"] for p in ps if p["analysis"] == "ne_vs_source_zenith"} == {"None"}
    args = [p["args"] for p in ps]
    assert any((a.get("render_options") or {}).get("m") == 4 for a in args)
    assert any(a.get("th_scopes") == ["object", "robust", "pixel"] for a in args)
    assert {p["surface"] for p in ps} >= {"semisphere", "semisphere_disc"}
    assert {p["noise"] for p in ps if p["analysis"] == "mask_scores"} == \
        {0.0, 0.1, 0.2, 0.025, 0.05}
    assert {a.get("kind") for a in args if "kind" in a} == {"Di", "Di-clamped"}
    assert json.dumps(sorted(I.INTERPRETATIONS)) and set(I.APPLIES["table5_3"]) <= \
        set(I.INTERPRETATIONS)
