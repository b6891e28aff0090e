"""Fixtures shared by the report tests."""
from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def small_panels(tmp_path_factory):
    """``(folder, names)``: the image panels built once at 24 x 24 (a build renders and
    solves a scene set, which takes seconds); tests copy the folder."""
    from psbench.report import panels

    out = tmp_path_factory.mktemp("panels")
    return out, panels.build_panels(out, size=24, log=lambda *a: None)
