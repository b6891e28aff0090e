"""Every public name the README, the documentation pages (docs/: getting started, the
user guide, the gallery examples) and the design notes give still imports, at the path
they give, without a deprecation warning."""
from __future__ import annotations

import importlib
import re
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the texts a user reads names in: the README, the docs' pages and gallery scripts
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")),
         *sorted((ROOT / "docs" / "guide").glob("*.md")),
         *sorted((ROOT / "docs" / "examples").glob("*.py"))]
README = "\n".join(p.read_text() for p in PAGES)
#: spelled like module paths in the README but not modules: entry-point groups, a file name
NOT_MODULES = {"psbench.masks", "psbench.methods", "psbench.analyses", "psbench.recipes",
               "psbench.run_kinds", "psbench.json"}
#: the public API and layout of the design notes (psbench's contract)
DESIGN = ["psbench.make_surface", "psbench.surface_from_height", "psbench.layout",
          "psbench.render", "psbench.solve", "psbench.normal_error", "psbench.intensity_error",
          "psbench.quality_factor", "psbench.integrate", "psbench.io.read_dataset",
          "psbench.io.write_dataset", "psbench.registry", "psbench.lights",
          "psbench.solve.masks", "psbench.solve.methods", "psbench.solve.methods.tsfit",
          "psbench.solve.methods.robust", "psbench.solve.methods.wps", "psbench.surfaces",
          "psbench.render", "psbench.integrate", "psbench.metrics", "psbench.analysis",
          "psbench.io", "psbench.calibrate", "psbench.capture", "psbench.forensic",
          "psbench.harness", "psbench.report", "psbench.experiments", "psbench.Result",
          "psbench.Scene", "psbench.Layout", "psbench.Surface", "psbench.PsbenchError"]


def _readme_names():
    alias = {"ps": "psbench", "pf": "psbench.forensic"}
    names = set()
    for head, rest in re.findall(r"\b(ps|pf|psbench)((?:\.[A-Za-z_][A-Za-z0-9_]*)+)", README):
        names.add(alias.get(head, head) + rest)
    for mod, items in re.findall(r"from (psbench[\w.]*) import ([\w, ]+)", README):
        names |= {f"{mod}.{n.strip()}" for n in items.split(",") if n.strip()}
    return sorted(names - NOT_MODULES)


def _resolve(dotted):
    """The module of the longest importable prefix, then attributes."""
    parts = dotted.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for p in parts[i:]:
            obj = getattr(obj, p)
        return obj
    raise ModuleNotFoundError(dotted)


def test_the_readme_names_enough():
    names = _readme_names()
    assert len(PAGES) > 20
    assert {"psbench.render.shadow_map", "psbench.io.read_x3p", "psbench.io.write_x3p",
            "psbench.forensic.reconstruct_heights"} <= set(names) and len(names) > 30


@pytest.mark.parametrize("name", _readme_names() + DESIGN)
def test_public_name_imports(name):
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        assert _resolve(name) is not None
