"""The Chapter 7 study (psbench.forensic.study) and experiment chapter7's page logic."""
import json

import numpy as np
import pandas as pd
import pytest

from psbench import PsbenchError, analysis, registry
from psbench.experiments import chapter7
from psbench.forensic import study

SMALL = {"guns": 2, "cases": 2, "integrators": ["poisson"], "regions": ["breech_face"]}


@pytest.fixture(scope="module")
def payload():
    """One ``method`` run on 2 guns x 2 cases at the smallest size the case allows."""
    return analysis.forensic("method", "None", size=256, seed=0, study=SMALL)


def test_case_keys_and_defaults():
    assert study.case_keys({"guns": 2, "cases": 3, "first_gun": 4}) == [
        (4, 1), (4, 2), (4, 3), (5, 1), (5, 2), (5, 3)]
    assert len(study.case_keys()) == study.STUDY["guns"] * study.STUDY["cases"]


@pytest.mark.parametrize("kwargs, word", [
    ({"part": "nope"}, "part"),
    ({"part": "method"}, "label"),
    ({"part": "method", "label": "Th-nope"}, "method"),
    ({"part": "truth", "study": {"gunz": 2}}, "gunz"),
    ({"part": "truth", "study": {"guns": 1}}, "guns"),
    ({"part": "truth", "study": {"cases": 2.5}}, "cases"),
    ({"part": "truth", "study": {"integrators": ["spline"]}}, "integrators"),
    ({"part": "truth", "study": {"time_size": "big"}}, "time_size"),
    ({"part": "truth", "size": 100}, "pixel_size"),
])
def test_bad_input(kwargs, word):
    with pytest.raises(PsbenchError, match=word):
        study.run(**kwargs)


def test_method_run_payload(payload):
    back = json.loads(json.dumps(payload))                       # json-able as stored
    assert back.keys() == payload.keys() and len(back["scores"]) == len(payload["scores"])
    assert payload["part"] == "method" and payload["label"] == "None"
    pc = pd.DataFrame(payload["per_case"])
    assert len(pc) == 4 and set(pc["method"]) == {"None"}
    assert (pc["ne"] > 0).all() and (pc["err_breech_face_um"] > 0).all()
    sc = pd.DataFrame(payload["scores"])
    assert len(sc) == 6 and sc["sister"].sum() == 2              # 2 sister pairs of 6
    assert sc["ccf"].between(-1, 1).all()
    # sisters registered near their true relative rotation
    assert (sc.loc[sc["sister"], "angle_error"] < 1.0).all()


def test_chapter7_aggregate_verdicts_and_figures(payload):
    rows = pd.DataFrame({"payload": [json.dumps(payload)]})
    agg = chapter7.aggregate(rows)
    row = "None / poisson"
    cells = agg[(agg["part"] == "breech face") & (agg["row"] == row)].set_index("column")
    sc = pd.DataFrame(payload["scores"])
    s, n = sc.loc[sc["sister"], "ccf"], sc.loc[~sc["sister"], "ccf"]
    assert cells.loc["separation", "value"] == pytest.approx(s.min() - n.max())
    assert cells.loc["sister median", "value"] == pytest.approx(s.median())
    assert 0.0 <= cells.loc["AUC", "value"] <= 1.0
    assert set(agg["part"]) >= {"breech face", "normals", "heights", "time"}
    out = chapter7.verdicts(agg, rows)
    assert len(out) == 12 and [v.thesis for v in out].count(False) == 2
    # without the other methods, references and panels most claims have no data
    assert sum(v.status == "INCONCLUSIVE" for v in out) >= 8
    figs = chapter7.figures(agg)
    assert [name for name, _ in figs] == ["chapter7_scores"]
    from psbench.report.figures import plt
    for _, f in figs:
        plt.close(f)


def test_chapter7_empty_and_registered():
    assert all(v.status == "INCONCLUSIVE" for v in chapter7.verdicts(pd.DataFrame(), None))
    assert registry.get("experiments", "chapter7").module is chapter7
    assert "forensic" in analysis.__all__


def test_solve_kwargs_lengths_in_um():
    from psbench.forensic.pipeline import solve_kwargs

    assert solve_kwargs("weighted Th-Hi-Re-Sh (um)", 4.9) == {
        "mask": "Th-Hi-Re-Sh", "weighted": True, "dilate_radius": 7, "kernel_size": 15,
        "smooth_sigma": 3.0}
    kw = solve_kwargs("weighted Th-Hi-Re-Sh (um)", 19.6)
    assert kw["dilate_radius"] == 2 and kw["kernel_size"] == 5
    assert kw["smooth_sigma"] == pytest.approx(0.75)
    assert solve_kwargs("WPS", 4.9) == {"method": "wps"}
    with pytest.raises(PsbenchError, match="valid choices"):
        solve_kwargs("nope", 4.9)


def test_roughness_of_a_plane_is_zero():
    from psbench.forensic.pipeline import roughness

    n = np.zeros((8, 9, 3), np.float32)
    n[..., 2] = 1.0
    m = np.ones((8, 9), bool)
    assert roughness(n, m) == pytest.approx(0.0, abs=1e-3)
    n[:, 5:] = (np.sin(0.1), 0.0, np.cos(0.1))
    assert roughness(n, m) > 0
    assert np.isnan(roughness(n, np.zeros_like(m)))
