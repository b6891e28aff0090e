"""Shared test fixtures for psbench."""
from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

REPO = Path(__file__).resolve().parents[1]

# the tests' plug-ins (the harness self-test kind ``noop``: tests/plugins/psbench_selftest)
# are found through their entry points by this process and by every process it starts
# (the psbench command, joblib and submitit workers), as an installed plug-in would be
PLUGINS = str(Path(__file__).resolve().parent / "plugins")
if PLUGINS not in sys.path:
    sys.path.insert(0, PLUGINS)
    importlib.invalidate_caches()
_pp = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]
if PLUGINS not in _pp:
    os.environ["PYTHONPATH"] = os.pathsep.join([PLUGINS] + _pp)
if "psbench.registry" in sys.modules:       # loaded before this file: read entry points again
    sys.modules["psbench.registry"].reload("run_kinds")


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


# slow / slurm tests deselected: counted where the tests are collected (this process, or
# each pytest-xdist worker, which reports its count back: the controller collects nothing)
_DESELECTED = {"here": 0, "workers": 0}


def _slow_or_slurm(item):
    return bool(item.get_closest_marker("slow") or item.get_closest_marker("slurm"))


def pytest_deselected(items):
    _DESELECTED["here"] += sum(map(_slow_or_slurm, items))


def pytest_sessionfinish(session):
    if hasattr(session.config, "workeroutput"):            # in an xdist worker
        session.config.workeroutput["psbench_deselected"] = _DESELECTED["here"]


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    # every worker collects the whole selection: the same count each, not a sum
    got = getattr(node, "workeroutput", {}).get("psbench_deselected", 0)
    _DESELECTED["workers"] = max(_DESELECTED["workers"], got)


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    """One line per skipped group saying how to enable it (the skip reasons are per test)."""
    skipped = terminalreporter.stats.get("skipped", [])
    n_data = sum(1 for rep in skipped
                 if "DiLiGenT" in str(rep.longrepr) or "realdata" in rep.keywords)
    if n_data:
        terminalreporter.write_line(
            f"psbench: {n_data} real-data test(s) skipped, DiLiGenT folders not found: "
            "set PSBENCH_DATA=<folder holding diligent/cat> to run them")
    deselected = max(_DESELECTED["here"], _DESELECTED["workers"])
    if deselected:
        terminalreporter.write_line(
            f"psbench: {deselected} slow/slurm test(s) deselected by default: "
            "run them with -m slow (full-size reproductions) or -m slurm")
