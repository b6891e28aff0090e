"""Reports of partial stores: a fresh store's ci pages beside kept ones, incomplete grids."""
from __future__ import annotations

import copy
import hashlib
import json
import re

import pytest
from test_report import _store, row, table5_3_rows

from psbench.harness.grid import expand
from psbench.harness.run import run_id
from psbench.report import pages as G
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


STATUSES = ("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE")


def _totals(page):
    """``{status: n}`` of the first totals line of a page ("**N claims: ...**")."""
    m = re.search(r"\*\*\d+ claims?: (\d+) SUPPORTED · (\d+) NOT SUPPORTED · "
                  r"(\d+) INCONCLUSIVE\*\*", page.read_text())
    return dict(zip(STATUSES, map(int, m.groups())))


def test_ci_report_of_a_fresh_store_keeps_the_pages_it_lacks(tmp_path, capsys):
    """A fresh store with one experiment writes that page into reports/ci; pages of the
    experiments it lacks are kept byte for byte (never replaced by NO DATA)."""
    out = tmp_path / "reports"
    old = _store(tmp_path / "old", table5_3_rows(size=40))
    assert main(["--results", str(old), "--out", str(out), "--scale", "ci"]) == 0
    kept_md = _digest(out / "ci" / "table5_3.md")
    first = json.loads((out / "ci" / "report.json").read_text())["experiments"]["table5_3"]
    assert first["size"] == T.scale_size("table5_3", "ci") == 40
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
    # the index still shows the whole report: the kept page is a row of the verdict table
    # (registered order, marked kept) and its verdicts are in the totals
    a, b = _totals(out / "ci" / "table5_3.md"), _totals(out / "ci" / "fig5_12.md")
    assert a == {k: first[k] for k in STATUSES}
    both = {k: a[k] + b[k] for k in STATUSES}
    assert _totals(out / "ci" / "index.md") == both
    rows = [ln for ln in index.splitlines() if ln.startswith("| [")]
    assert rows[0].startswith("| [table5_3](table5_3.html) |")
    assert rows[1].startswith("| [fig5_12](fig5_12.html) |")
    assert f"| {first['runs']} (kept) | {a['SUPPORTED']} | {a['NOT SUPPORTED']} | " \
           f"{a['INCONCLUSIVE']} |" in rows[0]
    assert f"| total |  | {first['runs'] + n} | {both['SUPPORTED']} |" in index
    assert "image sizes 32 x 32, 40 x 40;" in index           # fig5_12's and the kept page's
    # the kept page's claims are in Key findings (its first) and All verdicts (all)
    claims = S.page_verdicts(out / "ci" / "table5_3.md", "table5_3")
    assert len(claims) == sum(a.values()) > 0
    findings = index.split("## Key findings")[1].split("\n## ")[0]
    assert f"| {claims[0].status} | [table5_3](table5_3.html) | {claims[0].claim} |" \
        in findings.replace("\\|", "|")
    listed = index.split("## All verdicts")[1]
    assert sum(ln.startswith("| [table5_3]") for ln in listed.splitlines()) == len(claims)
    man = json.loads((out / "ci" / "report.json").read_text())
    assert man["experiments"]["table5_3"]["kept"] is True
    # the claims travel in report.json (stored when the page was built, carried over)
    assert S.kept_verdicts(out / "ci", "table5_3", man["experiments"]["table5_3"]) == claims
    assert [c["claim"] for c in first["claims"]] == [c.claim for c in claims]
    assert len(man["experiments"]["fig5_12"]["claims"]) == sum(b.values())
    assert man["experiments"]["table5_3"]["size"] == 40
    assert man["experiments"]["fig5_12"]["runs"] == n
    assert man["experiments"]["fig5_12"]["size"] == 32
    assert man["verdicts"] == both and man["in_totals"] == ["table5_3", "fig5_12"]
    assert list(man["experiments"]) == ["table5_3", "fig5_12"]
    assert S.existing(out / "ci")["with_data"] == {"table5_3", "fig5_12"}
    # --force replaces the kept page by what the store holds
    assert main(["--results", str(fresh), "--out", str(out), "--scale", "ci", "--force"]) == 0
    assert "NO DATA" in (out / "ci" / "table5_3.md").read_text()


def test_pages_written_without_a_manifest_are_kept_with_their_counts(tmp_path):
    old = tmp_path / "ci"
    old.mkdir()
    (old / "index.md").write_text("# psbench thesis reproduction report (scale: ci)\n")
    (old / "table5_3.md").write_text("# Table 5.3\n\nExperiment `table5_3`, scale `ci` (image "
                                     "size 40 x 40; the thesis used 512 x 512).\n\n"
                                     "Runs: 711 ok, 0 failed\n\n"
                                     "- **NOT SUPPORTED** — a\n- **SUPPORTED** — b\n"
                                     "- **NOT SUPPORTED** — c\n")
    got = S.kept(old, {"table5_3": 0, "fig5_12": 5})
    assert got == {"table5_3": {"runs": 711, "SUPPORTED": 1, "NOT SUPPORTED": 2,
                                "INCONCLUSIVE": 0, "kept": True, "size": 40}}
    assert S.kept(old, {"table5_3": 3, "fig5_12": 5}) == {}
    # a build from a store of fig5_12 alone counts the kept page in the index and totals
    fresh_rows, n = _grid_rows("fig5_12", "ci")
    assert main(["--results", str(_store(tmp_path / "fresh", fresh_rows)), "--out",
                 str(tmp_path), "--scale", "ci"]) == 0
    b = _totals(old / "fig5_12.md")
    both = {"SUPPORTED": 1 + b["SUPPORTED"], "NOT SUPPORTED": 2 + b["NOT SUPPORTED"],
            "INCONCLUSIVE": b["INCONCLUSIVE"]}
    index = (old / "index.md").read_text()
    assert _totals(old / "index.md") == both
    assert "| [table5_3](table5_3.html) | Table 5.3: overall results of all masks | " \
           "711 (kept) | 1 | 2 | 0 |" in index
    assert "image sizes 32 x 32, 40 x 40;" in index     # the kept page's size, from its text
    man = json.loads((old / "report.json").read_text())
    assert man["verdicts"] == both and man["experiments"]["table5_3"]["size"] == 40


def test_a_page_written_after_its_manifest_entry_is_kept_with_its_counts(tmp_path):
    """A page built alone after the last full build (its manifest entry says 0 runs) still
    holds data: it is kept, with the runs, PROVISIONAL verdicts and grid its text states."""
    old = tmp_path / "full"
    old.mkdir()
    (old / "report.json").write_text(json.dumps({"scale": "full", "experiments": {
        "table5_3": {"runs": 0, "SUPPORTED": 0, "NOT SUPPORTED": 0, "INCONCLUSIVE": 0},
        "fig5_12": {"runs": 150, "SUPPORTED": 3, "NOT SUPPORTED": 2, "INCONCLUSIVE": 0}}}))
    (old / "table5_3.md").write_text(
        "# Table 5.3\n\n**INCOMPLETE GRID: 6 of 30 runs present.** ...\n\nExperiment "
        "`table5_3`, scale `full` (image size 512 x 512; the thesis used 512 x 512).\n\n"
        "Runs: 6 ok, 0 failed\n\n**4 claims: 0 SUPPORTED · 1 NOT SUPPORTED · "
        "0 INCONCLUSIVE · 3 PROVISIONAL**\n")
    assert S.existing(old)["with_data"] == {"table5_3", "fig5_12"}
    got = S.kept(old, {"table5_3": 0, "fig5_12": 150})
    assert got == {"table5_3": {"runs": 6, "SUPPORTED": 0, "NOT SUPPORTED": 1,
                                "INCONCLUSIVE": 0, "PROVISIONAL": 3, "expected": 30,
                                "kept": True, "size": 512}}


def test_kept_pages_count_in_the_totals_only_when_their_experiment_does():
    """A kept page of an experiment outside the totals (interpretations) is listed but not
    counted, as when it is built; the manifest follows the given order."""
    assert not G.in_totals("interpretations") and G.in_totals("table5_3")
    kept = {"interpretations": {"runs": 110, "SUPPORTED": 48, "NOT SUPPORTED": 49,
                                "INCONCLUSIVE": 8, "kept": True, "size": 32},
            "table5_3": {"runs": 711, "SUPPORTED": 1, "NOT SUPPORTED": 2, "INCONCLUSIVE": 0,
                         "PROVISIONAL": 3, "kept": True, "size": None}}
    man = json.loads(S.manifest("ci", "results", [], "now", kept,
                                order=["table5_3", "interpretations"]))
    assert man["verdicts"] == {"SUPPORTED": 1, "NOT SUPPORTED": 2, "INCONCLUSIVE": 0,
                               "PROVISIONAL": 3}
    assert man["in_totals"] == ["table5_3"]
    assert list(man["experiments"]) == ["table5_3", "interpretations"]
    assert man["experiments"]["interpretations"] == kept["interpretations"]
    assert G.totals([], kept) == {"SUPPORTED": 1, "NOT SUPPORTED": 2, "INCONCLUSIVE": 0,
                                  "PROVISIONAL": 3}


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


def test_page_verdicts_reads_back_the_verdicts_a_page_states(tmp_path):
    from psbench.io.html import write_page
    from psbench.report.verdicts import Verdict

    vs = [Verdict("x", "A beats B | C (2 of 3)", "SUPPORTED", "gap 0.3 deg | margin 0.1",
                  'line 12: "A is best (clearly)"'),
          Verdict("x", "no quote here", "NOT SUPPORTED", "n/a"),
          Verdict("x", "own question", "INCONCLUSIVE", "-", thesis=False)]
    write_page(tmp_path, "x", [("h1", "x"), ("h2", "Verdicts on the thesis's conclusions"),
                               ("verdicts", vs[:2]), ("h2", "psbench's own questions"),
                               ("own_verdicts", vs[2:])], "x")
    assert S.page_verdicts(tmp_path / "x.md", "x") == vs[:2]
    assert S.page_verdicts(tmp_path / "missing.md", "x") == []


def test_kept_verdicts_come_from_the_manifest_else_from_the_page(tmp_path):
    from psbench.io.html import write_page
    from psbench.report.verdicts import Verdict

    vs = [Verdict("x", "A beats B", "SUPPORTED", "gap 0.3 deg", "line 12: A"),
          Verdict("x", "C beats D", "PROVISIONAL", "so far")]
    write_page(tmp_path, "x", [("h1", "x"), ("h2", "Verdicts on the thesis's conclusions"),
                               ("verdicts", vs[:1])], "x")
    entry = json.loads(S.manifest("ci", "results", [], "now", {"x": {"runs": 3}},
                                  order=["x"], verdicts={"x": vs}))["experiments"]["x"]
    assert entry["runs"] == 3 and len(entry["claims"]) == 2
    assert S.kept_verdicts(tmp_path, "x", entry) == vs            # the manifest's, not the page's
    assert S.kept_verdicts(tmp_path, "x", {"runs": 3}) == vs[:1]  # older manifest: the page
