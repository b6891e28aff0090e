"""Experiment breechface: its ci scale end to end on the shared scans, the page's logic."""
from __future__ import annotations

import pandas as pd
import pytest

from psbench import PsbenchError
from psbench.experiments import breechface as E
from psbench.forensic import breechface_runs as R
from psbench.forensic.scans import scans_folder
from psbench.harness.app import main
from psbench.harness.grid import expand, load
from psbench.harness.store import read_store
from psbench.report.cli import build

needs_scans = pytest.mark.skipif(not (scans_folder() / "guns.csv").is_file(),
                                 reason="the shared X3P scans are not here ($PSBENCH_X3P)")


def test_grid_runs_every_label_the_scan_and_the_panels():
    runs = expand(load("breechface"), "full")
    combos = [(r["args"]["label"], r["args"]["finish"], r["args"]["integrator"])
              for r in runs if r["args"]["part"] == "method"]
    assert sorted(combos) == sorted((m, f, i) for m in R.LABELS for f in ("brass", "nickel")
                                    for i in ("poisson", "bilateral"))
    assert sorted(r["args"]["part"] for r in runs if r["args"]["part"] != "method") == [
        "panels", "scan"]
    # a full-scale run takes hours: it keeps what it finished, so a stopped one resumes
    assert {r["study"]["cache"].endswith("/breechface") for r in runs} == {True}
    # and reads the comparisons of earlier checkouts from the committed pairs table
    assert {r["study"]["pairs_table"] for r in runs} == {"reports/data/breechface_pairs.parquet"}
    ci = expand(load("breechface"), "ci")
    assert {tuple(r["study"]["methods"]) for r in ci} == {("None", "Th-Hi-Re-Sh", "recipe")}


def test_operational_study_keys_are_not_part_of_a_runs_identity():
    from psbench.harness.params import run_id

    run = expand(load("breechface"), "full")[0]
    moved = {**run, "study": {**run["study"], "cache": "/elsewhere/cache",
                              "pairs_table": "other.parquet", "jobs": 2}}
    assert run_id(moved) == run_id(run)
    bare = {**run, "study": {k: v for k, v in run["study"].items()
                             if k not in ("cache", "pairs_table", "jobs")}}
    assert run_id(bare) == run_id(run)
    # what the study computes is part of it
    other = {**run, "study": {**run["study"], "finishes": ["brass"]}}
    assert run_id(other) != run_id(run)
    # another analysis declares none: its study keys all count
    ch7 = {**run, "analysis": "forensic", "study": {**run["study"], "cache": "/x"}}
    assert run_id(ch7) != run_id({**ch7, "study": run["study"]})


@pytest.mark.parametrize("kwargs, word", [
    ({"part": "nope"}, "part"),
    ({"part": "method", "label": "Th-nope"}, "label"),
    ({"part": "scan", "study": {"gunz": 1}}, "gunz"),
    ({"part": "scan", "study": {"finishes": ["gold"]}}, "finishes"),
    ({"part": "scan", "study": {"integrators": ["spline"]}}, "integrators"),
    ({"part": "scan", "study": {"methods": ["magic"]}}, "methods"),
    ({"part": "scan", "study": {"jobs": 0}}, "jobs"),
    ({"part": "method", "label": "None", "finish": "gold"}, "finish"),
    ({"part": "method", "label": "None", "integrator": "spline"}, "integrator"),
    ({"part": "scan", "finish": "brass"}, "finish"),
    ({"part": "scan", "study": {"cache": 5}}, "cache"),
    ({"part": "scan", "study": {"pairs_table": 5}}, "pairs_table"),
])
def test_bad_input(kwargs, word):
    with pytest.raises(PsbenchError, match=word):
        R.run(**kwargs)


def test_a_label_outside_the_scale_is_skipped_at_once():
    out = R.run("method", "robust", study={"methods": ["None"]})
    assert out["skipped"] is True and "scores" not in out
    for kw in ({"finish": "nickel"}, {"integrator": "bilateral"}):
        out = R.run("method", "None", study={"finishes": ["brass"],
                                             "integrators": ["poisson"]}, **kw)
        assert out["skipped"] is True and "scores" not in out


@needs_scans
def test_unknown_gun_is_named():
    with pytest.raises(PsbenchError, match="99"):
        R.run("scan", study={"guns": ["99"]})


def test_empty_aggregate_is_inconclusive():
    agg = E.aggregate(pd.DataFrame({"payload": []}))
    assert agg.empty
    assert all(v.status == "INCONCLUSIVE" for v in E.verdicts(agg))


@needs_scans
def test_ci_scale_end_to_end(tmp_path):
    root = tmp_path / "results"
    main(["+experiment=breechface", "scale=ci", "jobs=1", f"results_dir={root}"])
    rows = read_store(root, experiment="breechface")
    assert len(rows) == 30 and set(rows["status"]) == {"ok"}
    agg = E.aggregate(rows[rows.status == "ok"])
    assert set(agg["part"]) == {"brass"}
    got = set(agg["row"])
    assert got == {"scan", "None / poisson", "Th-Hi-Re-Sh / poisson", "recipe / poisson"}
    sc = agg.attrs["scores"]
    assert len(sc) == 4 * 6 and sc.same_gun.sum() == 4 * 2       # 4 maps x 6 pairs
    # every value the page shows is a number; the scans separate at this scale
    assert agg["value"].notna().all()
    auc = agg[(agg.row == "scan") & (agg.column == "AUC CMC")]["value"].item()
    assert 0.5 <= auc <= 1.0
    assert len(E.verdicts(agg)) == 4
    assert [n for n, _ in E.figures(agg)] == ["breechface_roc", "breechface_scores",
                                              "breechface_pair"]
    out = tmp_path / "reports"
    build(root, out, "ci", log=lambda *a: None, experiments=("breechface",))
    md = (out / "breechface.md").read_text()
    assert md.startswith("# Real breech faces") and "recipe / poisson" in md


def test_figure_groups_follow_the_method_order_scans_last():
    """The score and ROC figures order their groups by the study's method labels, a
    method's integrators side by side and the scans last, whatever the stored order."""
    from psbench.experiments._breechface_figures import _labels, _tick

    stored = [("recipe", "bilateral"), ("scan", "-"), ("tsfit", "poisson"),
              ("None", "bilateral"), ("recipe", "poisson"), ("None", "poisson")]
    sc = pd.DataFrame(stored, columns=["method", "integrator"])
    assert _labels(sc) == [("None", "poisson"), ("None", "bilateral"), ("tsfit", "poisson"),
                           ("recipe", "poisson"), ("recipe", "bilateral"), ("scan", "-")]
    assert _tick("weighted Th-Hi-Re-Sh", "bilateral") == "weighted\nTh-Hi-Re-Sh\nbilateral"
    assert _tick("scan", "-") == "scan"
