"""Reports of partial stores: a fresh store's ci pages beside kept ones, incomplete grids."""
from __future__ import annotations

import copy
import hashlib
import json

import pytest
from test_report import _store, row, table5_3_rows

from psbench.harness.grid import expand
from psbench.harness.run import run_id
from psbench.report import scales as S
from psbench.report import tables as T
from psbench.report.cli import main

NAMES = ["table5_3", "fig5_12"]


@pytest.fixture(autouse=True)
def few_experiments(monkeypatch):
    monkeypatch.setattr(T, "names", lambda: list(NAMES))


def _grid_rows(name, scale, keep=None):
    """Rows with the run ids of ``name``'s current grid at ``scale`` (the first ``keep``)."""
    params = list(expand(copy.deepcopy(T.grid(name)), scale))[:keep]
    out = []
    for i, p in enumerate(params):
        r = row(name, 2000 + i, **{k: v for k, v in p.items()
                                   if k in ("surface", "lights", "noise", "size", "mask",
                                            "method", "seed", "model")},
                n_images=8, ne_mean=5 + 10 * p["noise"] + (1 if p["mask"] == "RA" else 0))
        r["run_id"] = run_id(p)
        out.append(r)
    return out, len(params)


def _digest(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_ci_report_of_a_fresh_store_keeps_the_pages_it_lacks(tmp_path, capsys):
    """A fresh store with one experiment writes that page into reports/ci; pages of the
    experiments it lacks are kept byte for byte (never replaced by NO DATA)."""
    out = tmp_path / "reports"
    old = _store(tmp_path / "old", table5_3_rows(size=40))
    assert main(["--results", str(old), "--out", str(out), "--scale", "ci"]) == 0
    kept_md = _digest(out / "ci" / "table5_3.md")
    fresh_rows, n = _grid_rows("fig5_12", "ci")
    fresh = _store(tmp_path / "fresh", fresh_rows)
    capsys.readouterr()
    assert main(["--results", str(fresh), "--out", str(out), "--scale", "ci"]) == 0
    assert "kept the pages of table5_3" in capsys.readouterr().out
    assert _digest(out / "ci" / "table5_3.md") == kept_md
    page = (out / "ci" / "fig5_12.md").read_text()
    assert f"Runs: {n} ok" in page and "INCOMPLETE" not in page and "PROVISIONAL" not in page
    index = (out / "ci" / "index.md").read_text()
    assert "Pages kept from an earlier build (1)" in index and "table5_3.html" in index
    man = json.loads((out / "ci" / "report.json").read_text())
    assert man["experiments"]["table5_3"]["kept"] is True
    assert man["experiments"]["fig5_12"]["runs"] == n
    assert S.existing(out / "ci")["with_data"] == {"table5_3", "fig5_12"}
    # --force replaces the kept page by what the store holds
    assert main(["--results", str(fresh), "--out", str(out), "--scale", "ci", "--force"]) == 0
    assert "NO DATA" in (out / "ci" / "table5_3.md").read_text()


def test_pages_written_without_a_manifest_are_kept_with_their_counts(tmp_path):
    old = tmp_path / "ci"
    old.mkdir()
    (old / "index.md").write_text("# psbench thesis reproduction report (scale: ci)\n")
    (old / "table5_3.md").write_text("# Table 5.3\n\nRuns: 711 ok, 0 failed\n\n"
                                     "- **NOT SUPPORTED** — a\n- **SUPPORTED** — b\n"
                                     "- **NOT SUPPORTED** — c\n")
    got = S.kept(old, {"table5_3": 0, "fig5_12": 5})
    assert got == {"table5_3": {"runs": 711, "SUPPORTED": 1, "NOT SUPPORTED": 2,
                                "INCONCLUSIVE": 0, "kept": True}}
    assert S.kept(old, {"table5_3": 3, "fig5_12": 5}) == {}


def test_an_incomplete_grid_is_said_at_the_top_and_its_verdicts_are_provisional(tmp_path):
    rows, n = _grid_rows("fig5_12", "ci", keep=40)
    full, _ = _grid_rows("fig5_12", "ci")
    out = tmp_path / "reports"
    assert main(["--results", str(_store(tmp_path / "part", rows)), "--out", str(out),
                 "--scale", "ci"]) == 0
    page = (out / "ci" / "fig5_12.md").read_text()
    head = page.split("Verdicts on the thesis")[0]
    assert f"INCOMPLETE GRID: 40 of {len(full)} runs present" in head
    verdict_lines = [ln for ln in page.splitlines() if ln.startswith("| PROVISIONAL")]
    assert verdict_lines
    assert all(f"on 40 of {len(full)} runs" in ln for ln in verdict_lines)
    for status in ("| SUPPORTED |", "| NOT SUPPORTED |", "| INCONCLUSIVE |"):
        assert status not in page                       # no final verdict on a partial grid
    index = (out / "ci" / "index.md").read_text()
    assert f"INCOMPLETE GRIDS: fig5_12 (40 of {len(full)} runs)" in index
    assert f"40 of {len(full)} (incomplete grid)" in index
    man = json.loads((out / "ci" / "report.json").read_text())
    assert man["experiments"]["fig5_12"]["PROVISIONAL"] > 0
    assert man["experiments"]["fig5_12"]["SUPPORTED"] == 0
    # the complete grid: final verdicts, no note
    assert main(["--results", str(_store(tmp_path / "all", full)), "--out", str(out),
                 "--scale", "ci"]) == 0
    page = (out / "ci" / "fig5_12.md").read_text()
    assert "INCOMPLETE" not in page and "PROVISIONAL" not in page
    assert "| SUPPORTED |" in page or "| NOT SUPPORTED |" in page
