"""The user guide's "Writing a plug-in" package, installed and used end to end.

The code blocks of that page (``docs/guide/plugins.md``) (each starts with ``# psbplug/<file>``, the
entry points with ``# pyproject.toml of psbplug``) are written to a temporary folder
with the ``*.dist-info`` that ``pip install`` leaves behind (METADATA and
``entry_points.txt``) and put on ``sys.path``. Its mask, method, surface and experiment
must then work through ``ps.solve``, the ``psbench`` command line (run, ``--help``,
``+experiment=``) and ``psbench-report`` without any list in psbench being edited. The
page therefore cannot drift from what works.
"""
from __future__ import annotations

import configparser
import importlib
import re
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError, registry
from psbench.harness.app import main
from psbench.harness.store import read_store
from psbench.report.cli import build

PAGE = Path(__file__).resolve().parents[1] / "docs" / "guide" / "plugins.md"
GROUPS = ("masks", "methods", "surfaces", "experiments")


def _blocks():
    """``{first-line tag: code}`` of the fenced blocks of the plug-in page."""
    section = PAGE.read_text()
    out = {}
    for lang, body in re.findall(r"```(\w+)\n(.*?)```", section, flags=re.S):
        first, _, rest = body.partition("\n")
        out[first.lstrip("# ").strip()] = rest
    return out


def _forget(prefix):
    for name in [m for m in sys.modules if m == prefix or m.startswith(prefix + ".")]:
        del sys.modules[name]


@pytest.fixture(scope="module")
def psbplug(tmp_path_factory):
    blocks = _blocks()
    site = tmp_path_factory.mktemp("site")
    pkg = site / "psbplug"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    files = [k for k in blocks if k.startswith("psbplug/")]
    assert sorted(files) == ["psbplug/bump.py", "psbplug/dark.py", "psbplug/plugexp.py",
                             "psbplug/plugexp.yaml", "psbplug/shrink.py"]
    for name in files:
        (site / name).write_text(blocks[name])
    eps = tomllib.loads(blocks["pyproject.toml of psbplug"])["project"]["entry-points"]
    ini = configparser.ConfigParser()
    ini.optionxform = str
    for group, entries in eps.items():
        ini[group] = entries
    info = site / "psbplug-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: psbplug\nVersion: 0.1\n")
    with open(info / "entry_points.txt", "w") as fh:
        ini.write(fh)
    sys.path.insert(0, str(site))
    importlib.invalidate_caches()
    registry.reload()
    try:
        yield site
    finally:
        sys.path.remove(str(site))
        _forget("psbplug")
        importlib.invalidate_caches()
        registry.reload()


def test_every_piece_is_registered(psbplug):
    assert registry.get("masks", "Dark").stage == "image"
    assert registry.get("methods", "shrink").options.__name__ == "ShrinkOptions"
    assert registry.get("surfaces", "bump").name == "bump"
    assert registry.get("experiments", "plugexp").grid.name == "plugexp.yaml"
    for group in GROUPS:                    # the built-ins are still there beside them
        assert len(registry.names(group)) > 1


def test_python_api(psbplug):
    surf = ps.make_surface("bump", size=32, width=0.2)
    lay = ps.layout("45x8")
    sc = ps.render(surf, lay, model="lambert")
    th = ps.solve(sc.images, lay, mask="Th", object_mask=surf.object_mask)
    res = ps.solve(sc.images, lay, mask="Th-Dark", method="shrink", factor=0.25,
                   object_mask=surf.object_mask)
    assert res.mask == "Th-Dark" and res.method == "shrink"
    assert not (res.valid & ~th.valid).any()           # AND of validity with Th
    np.testing.assert_allclose(res.normals[surf.object_mask], th.normals[surf.object_mask],
                               atol=1e-5)              # shadow-free: Dark drops nothing used
    on = surf.object_mask & (th.albedo > 0)
    np.testing.assert_allclose(res.albedo[on], 0.25 * th.albedo[on], rtol=1e-4)
    with pytest.raises(PsbenchError, match="factor must be a number in"):
        ps.solve(sc.images, lay, method="shrink", factor=2.0)
    with pytest.raises(PsbenchError, match=r"t_dark.*out of range"):
        ps.solve(sc.images, lay, mask="Dark", thresholds={"t_dark": 3.0})


def test_command_line_run_and_help(psbplug, tmp_path, capsys):
    root = tmp_path / "results"
    main(["surface=bump", "size=24", "lights=45x8", "model=lambert", "noise=0",
          "mask=Th-Dark", "method=shrink", "options.factor=0.25", f"results_dir={root}"])
    row = read_store(root).iloc[0]
    assert row["status"] == "ok" and row["mask"] == "Th-Dark" and row["method"] == "shrink"
    assert '"factor": 0.25' in row["options"] and row["ne_mean"] < 5
    capsys.readouterr()
    main(["--help"])
    text = capsys.readouterr().out
    for word in ("Dark", "shrink", "factor", "bump", "plugexp"):
        assert word in text


def test_experiment_and_report_page(psbplug, tmp_path):
    root = tmp_path / "results"
    main(["+experiment=plugexp", "scale=ci", "jobs=1", f"results_dir={root}"])
    df = read_store(root, experiment="plugexp")
    assert len(df) == 4 and set(df["status"]) == {"ok"}
    assert set(df["mask"]) == {"None", "Th-Dark"} and set(df["method"]) == {"ps", "shrink"}
    out = tmp_path / "reports"
    build(root, out, "ci", log=lambda *a: None, experiments=("plugexp",))
    md = (out / "plugexp.md").read_text()
    assert md.startswith("# Plug-in: Dark and shrink on the bump")
    assert "Th-Dark is no worse than None" in md and "Th-Dark" in md and "shrink" in md
    assert "SUPPORTED" in md
    html = (out / "plugexp.html").read_text()
    assert "Plug-in: Dark and shrink on the bump" in html
