"""Shared test fixtures for psbench."""
from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

REPO = Path(__file__).resolve().parents[1]


def data_root() -> Path | None:
    """Folder holding ``diligent/{cat,bear}``: $PSBENCH_DATA, else <repo>/../shared/data."""
    env = os.environ.get("PSBENCH_DATA")
    root = Path(env) if env else REPO.parent / "shared" / "data"
    return root if (root / "diligent").is_dir() else None


@pytest.fixture(scope="session")
def diligent():
    """Path to the DiLiGenT folders; skips the test with a clear message when absent."""
    root = data_root()
    if root is None:
        pytest.skip("DiLiGenT folders not found: set PSBENCH_DATA=<folder holding "
                    "diligent/cat> (default <repo>/../shared/data)")
    return root / "diligent"


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """One line per skipped group saying how to enable it (the skip reasons are per test)."""
    skipped = terminalreporter.stats.get("skipped", [])
    n_data = sum(1 for rep in skipped
                 if "DiLiGenT" in str(rep.longrepr) or "realdata" in rep.keywords)
    if n_data:
        terminalreporter.write_line(
            f"psbench: {n_data} real-data test(s) skipped, DiLiGenT folders not found: "
            "set PSBENCH_DATA=<folder holding diligent/cat> to run them")
    deselected = sum(1 for item in terminalreporter.stats.get("deselected", [])
                     if item.get_closest_marker("slow") or item.get_closest_marker("slurm"))
    if deselected:
        terminalreporter.write_line(
            f"psbench: {deselected} slow/slurm test(s) deselected by default: "
            "run them with -m slow (full-size reproductions) or -m slurm")
