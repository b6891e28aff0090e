"""psbench-report never replaces a report that holds data with an emptier one."""
from __future__ import annotations

import hashlib
import json
import shutil

import pandas as pd
import pytest
from test_report import _store, row, table5_3_rows

from psbench.report import scales as S
from psbench.report import tables as T
from psbench.report.cli import build, main

#: the experiments these tests report (all registered ones would only be slower)
NAMES = ["table2_1", "table5_3", "fig4_9", "fig5_12"]


@pytest.fixture(autouse=True)
def few_experiments(monkeypatch):
    monkeypatch.setattr(T, "names", lambda: list(NAMES))


def _snapshot(folder):
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _fig5_12_rows(size, start=1000):
    return [row("fig5_12", start + i, surface=s, lights="45x8", n_images=8, noise=nz, size=size,
                mask=m, ne_mean=5 + 10 * nz)
            for i, (s, nz, m) in enumerate((s, nz, m) for s in ("semisphere", "penny")
                                           for nz in (0.0, 0.1) for m in ("None", "Th"))]


@pytest.fixture(scope="module")
def _built_report(tmp_path_factory):
    """Built once per module (a build takes seconds); each test gets its own copy."""
    tmp = tmp_path_factory.mktemp("full_report")
    full = _store(tmp / "full", table5_3_rows(size=512) + _fig5_12_rows(512))
    out = tmp / "reports"
    mp = pytest.MonkeyPatch()
    mp.setattr(T, "names", lambda: list(NAMES))
    try:
        assert main(["--results", str(full), "--out", str(out)]) == 0
    finally:
        mp.undo()
    assert not (out / "ci").exists()                     # the store holds no ci-scale runs
    return out


@pytest.fixture
def full_report(_built_report, tmp_path):
    """A full-scale report (table5_3 and fig5_12 at 512^2) in tmp_path/reports."""
    out = tmp_path / "reports"
    shutil.copytree(_built_report, out)
    return out


def test_builder_refuses_to_overwrite_full_report_from_ci_only_store(full_report, tmp_path,
                                                                     capsys):
    out = full_report
    before = _snapshot(out)
    assert S.existing(out)["scale"] == "full"
    assert S.existing(out)["with_data"] == {"table5_3", "fig5_12"}
    ci = _store(tmp_path / "ci", table5_3_rows(size=40))           # only `scale=ci` runs
    # the builder itself refuses, before writing anything
    with pytest.raises(S.ReportRefused, match="no full-scale runs"):
        build(ci, out, "full", log=lambda *a: None)
    assert _snapshot(out) == before
    # so does the command with an explicit scale: one line, exit status 2
    capsys.readouterr()
    assert main(["--results", str(ci), "--out", str(out), "--scale", "full"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("psbench-report: refusing") and "\n" not in err
    assert _snapshot(out) == before
    # the README's command (no options) reports the scale the store holds: ci into out/ci,
    # leaving the full-scale report untouched
    assert main(["--results", str(ci), "--out", str(out)]) == 0
    assert {k: v for k, v in _snapshot(out).items() if not k.startswith("ci/")} == before
    assert S.existing(out / "ci")["scale"] == "ci"
    assert S.existing(out / "ci")["with_data"] == {"table5_3"}
    assert "(scale: ci)" in (out / "ci" / "index.md").read_text()


def test_empty_store_never_replaces_a_report(full_report, tmp_path, capsys):
    before = _snapshot(full_report)
    capsys.readouterr()
    assert main(["--results", str(tmp_path / "nothing"), "--out", str(full_report)]) == 2
    assert "holds no full-scale runs" in capsys.readouterr().err
    assert _snapshot(full_report) == before


def test_pages_with_data_are_not_blanked_unless_forced(full_report, tmp_path):
    part = _store(tmp_path / "part", table5_3_rows(size=512))     # fig5_12 missing
    before = _snapshot(full_report)
    before_man = (full_report / "report.json").read_text()
    build(part, full_report, "full", log=lambda *a: None)
    # fig5_12's page, figures and table are kept byte for byte (not replaced by NO DATA)
    mine = lambda snap: {k: v for k, v in snap.items() if "fig5_12" in k}  # noqa: E731
    assert mine(before) and mine(_snapshot(full_report)) == mine(before)
    assert S.existing(full_report)["with_data"] == {"table5_3", "fig5_12"}
    index = (full_report / "index.md").read_text()
    assert "Pages kept from an earlier build (1)" in index
    # the kept page is still a row of the verdict table, and its verdicts are in the totals
    man = json.loads((full_report / "report.json").read_text())
    assert man["experiments"]["fig5_12"]["kept"] is True
    assert "| [fig5_12](fig5_12.html) |" in index and \
        f"| {man['experiments']['fig5_12']['runs']} (kept) |" in index
    assert man["in_totals"] == NAMES                      # registered order, kept included
    assert man["verdicts"] == {k: sum(man["experiments"][n][k] for n in man["in_totals"])
                               for k in ("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE")}
    assert man["verdicts"] == json.loads(before_man)["verdicts"]     # the same report
    build(part, full_report, "full", log=lambda *a: None, force=True)
    assert S.existing(full_report)["with_data"] == {"table5_3"}
    assert "NO DATA" in (full_report / "fig5_12.md").read_text()


def test_a_folder_of_another_scale_is_not_overwritten(full_report, tmp_path):
    ci = _store(tmp_path / "ci", table5_3_rows(size=40))
    with pytest.raises(S.ReportRefused, match="holds a full-scale report"):
        build(ci, full_report, "ci", log=lambda *a: None)


def test_reports_written_before_the_manifest_are_recognized(tmp_path):
    old = tmp_path / "old"
    old.mkdir()
    (old / "index.md").write_text("# psbench thesis reproduction report (scale: full)\n")
    (old / "table5_3.md").write_text("# Table 5.3\n\nRuns: 1185 ok, 0 failed (of 1185)\n")
    (old / "fig4_9.md").write_text("# Fig. 4.9\n\nRuns: 0 ok\n\nNO DATA: ...\n")
    got = S.existing(old)
    assert got == {"scale": "full", "with_data": {"table5_3"}, "runs": 1185}
    with pytest.raises(S.ReportRefused):               # a store with no full-scale run
        S.check(old, "full", {"table5_3": 0, "fig4_9": 0}, "results")
    S.check(old, "full", {"table5_3": 0, "fig4_9": 3}, "results")
    assert set(S.kept(old, {"table5_3": 0, "fig4_9": 3})) == {"table5_3"}   # page kept
    S.check(old, "full", {"table5_3": 5, "fig4_9": 0}, "results")      # nothing lost
    assert S.existing(tmp_path / "none") is None


def test_held_scales_ignore_runs_shared_by_both_scales():
    df = pd.DataFrame(table5_3_rows(size=40)[:3] + _fig5_12_rows(512)[:2]
                      + [row("table2_1", 9000, kind="cond", count=4, zenith=30.0, cond=2.4)])
    held = S.held(df)
    assert held == {"full": ["fig5_12"], "ci": ["table5_3"]}
    assert S.held(df.iloc[0:0]) == {"full": [], "ci": []}
    assert S.folder("reports", "full").as_posix() == "reports"
    assert S.folder("reports", "ci").as_posix() == "reports/ci"


def test_pages_are_not_rebuilt_from_fewer_rows(full_report, tmp_path, capsys):
    """A store that lost rows (e.g. a corrupt compact file) never silently rebuilds the
    pages with fewer runs: one line, exit 2, the old pages kept."""
    rows = table5_3_rows(size=512)
    fewer = _store(tmp_path / "fewer", rows[: len(rows) // 2] + _fig5_12_rows(512))
    before = _snapshot(full_report)
    capsys.readouterr()
    assert main(["--results", str(fewer), "--out", str(full_report)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fewer runs than its pages report" in err[0]
    assert f"table5_3: {len(rows) // 2} of {len(rows)}" in err[0]
    assert _snapshot(full_report) == before
