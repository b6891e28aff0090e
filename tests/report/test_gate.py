"""The CI gate: planted regressions fail, unchanged results pass, baselines only via update."""
from __future__ import annotations

import copy

import pandas as pd
import pyarrow.parquet as pq
import pytest

from psbench.harness.schema import row_table
from psbench.report import gate

from test_report import row, table5_3_rows

ONLY = ("table5_3", "table5_4")


def table5_4_rows(ne=None):
    rows, i = [], 0
    for cfg in ("30x8+60x8", "35x8+65x8", "30x4+45x4+60x4"):
        for s in ("sombrero1", "sombrero2", "sombrero3"):
            rows.append(row("table5_4", 3000 + i, surface=s, lights=cfg, size=48,
                            ne_mean=(ne or {}).get(cfg, 5.0 + i * 0.01)))
            i += 1
    return rows


def write_store(root, rows):
    """Replace the store at ``root`` by ``rows`` (one compact file per sweep)."""
    import shutil

    if root.exists():
        shutil.rmtree(root)
    (root / "compact").mkdir(parents=True)
    by = {}
    for r in rows:
        by.setdefault(r["sweep"], []).append(r)
    for sweep, rs in by.items():
        pq.write_table(row_table(rs), root / "compact" / f"{sweep}.parquet")
    return root


@pytest.fixture
def setup(tmp_path):
    rows = table5_3_rows(size=40) + table5_4_rows()
    res = write_store(tmp_path / "results", rows)
    base = tmp_path / "baselines"
    assert gate.update(res, base, ONLY, out=lambda *a: None) == 0
    assert (base / "table5_3.csv").is_file() and (base / "tolerances.yaml").is_file()
    return tmp_path, rows, res, base


def run_check(res, base):
    lines = []
    code = gate.check(res, base, ONLY, out=lines.append)
    return code, "\n".join(lines)


def test_unchanged_results_pass(setup):
    _, _, res, base = setup
    code, text = run_check(res, base)
    assert code == 0, text
    assert "GATE PASSED" in text


def test_th_two_degrees_worse_fails(setup):
    _, rows, res, base = setup
    bad = copy.deepcopy(rows)
    for r in bad:
        if r["mask"] == "Th":
            r["ne_mean"] += 2.0
    write_store(res, bad)
    code, text = run_check(res, base)
    assert code == 1
    assert "GATE FAILED" in text and "all/Th/ne" in text and "four/Th/ne" in text
    assert "all/None/ne" not in text            # only the planted cells are reported


def test_disabled_mask_fails(setup):
    """Th silently replaced by None's results (a disabled mask) must fail the gate."""
    _, rows, res, base = setup
    none = {(r["surface"], r["lights"], r["noise"]): r for r in rows
            if r["sweep"] == "table5_3" and r["mask"] == "None"}
    bad = []
    for r in rows:
        if r["sweep"] == "table5_3" and r["mask"] == "Th":
            r = dict(none[(r["surface"], r["lights"], r["noise"])], mask="Th",
                     run_id=r["run_id"])
        bad.append(r)
    write_store(res, bad)
    code, text = run_check(res, base)
    assert code == 1 and "all/Th/ne" in text and "all/Th/qf_total" in text


def test_missing_cells_fail_and_new_cells_do_not(setup):
    _, rows, res, base = setup
    bad = [r for r in rows if not (r["sweep"] == "table5_4" and r["lights"] == "35x8+65x8")]
    bad.append(row("table5_4", 9999, surface="sombrero1", lights="25x8+65x8", size=48,
                   ne_mean=4.0))
    write_store(res, bad)
    code, text = run_check(res, base)
    assert code == 1 and "missing" in text and "35x8+65x8" in text
    assert "1 new" in text


def test_timing_is_one_sided_and_loose(setup):
    _, rows, res, base = setup
    slow3 = copy.deepcopy(rows)
    for r in slow3:
        r["t_solve"] *= 3.0
    write_store(res, slow3)
    assert run_check(res, base)[0] == 0          # 3x slower: within the 5x bound
    fast = copy.deepcopy(rows)
    for r in fast:
        r["t_solve"] *= 0.01
    write_store(res, fast)
    assert run_check(res, base)[0] == 0          # faster never fails
    slow = copy.deepcopy(rows)
    for r in slow:
        if r["sweep"] == "table5_3":
            r["t_solve"] = r["t_solve"] * 20 + 1.0
    write_store(res, slow)
    code, text = run_check(res, base)
    assert code == 1 and "/time" in text


def test_tolerances_file_overrides(setup):
    tmp, rows, res, base = setup
    bad = copy.deepcopy(rows)
    for r in bad:
        if r["mask"] == "Th":
            r["ne_mean"] += 2.0
    write_store(res, bad)
    (base / "tolerances.yaml").write_text("experiments:\n  table5_3:\n    ne: {abs: 5.0}\n")
    assert run_check(res, base)[0] == 0


def test_missing_baseline_and_refused_update(tmp_path):
    res = write_store(tmp_path / "results", table5_4_rows())
    lines = []
    assert gate.check(res, tmp_path / "none", ("table5_4",), out=lines.append) == 2
    assert "missing baseline files" in "\n".join(lines)
    # update refuses when an experiment has no ci rows (baselines never silently emptied)
    assert gate.update(res, tmp_path / "b", ("table5_3",), out=lines.append) == 1
    assert not (tmp_path / "b" / "table5_3.csv").exists()


def test_cli_exit_codes(setup):
    _, rows, res, base = setup
    args = ["check", "--results", str(res), "--baselines", str(base), "--only", ",".join(ONLY)]
    assert gate.main(args) == 0
    bad = copy.deepcopy(rows)
    for r in bad:
        if r["mask"] == "Th-Hi-Re-Sh":
            r["ne_mean"] += 1.0
    write_store(res, bad)
    assert gate.main(args) == 1
    with pytest.raises(SystemExit):
        gate.main(["check", "--only", "nonsense"])


def test_baseline_csv_is_readable_text(setup):
    _, _, _, base = setup
    df = pd.read_csv(base / "table5_3.csv", dtype=str)
    assert list(df.columns) == ["part", "row", "column", "value", "n"]
    assert ((df["part"] == "all") & (df["row"] == "Th") & (df["column"] == "ne")).sum() == 1
