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
        pytest.skip("DiLiGenT data not found: set PSBENCH_DATA to the folder holding "
                    "diligent/cat and diligent/bear (default <repo>/../shared/data)")
    return root / "diligent"
