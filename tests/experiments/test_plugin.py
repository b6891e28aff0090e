"""A third-party experiment: one module + its YAML, registered like an installed package.

The package is written to a temporary folder with a ``*.dist-info`` (METADATA and
``entry_points.txt``) and put on ``sys.path``, which is exactly what ``pip install``
leaves behind; psbench must then run it from the command line (``+experiment=tiny``,
in-process), report it and gate it without any list of experiments being edited.
"""
from __future__ import annotations

import importlib
import re
import sys
import types

import pytest

from psbench import registry
from psbench.harness.app import main
from psbench.harness.store import read_store
from psbench.report import gate
from psbench.report import tables as T
from psbench.report.cli import build

MODULE = '''\
"""Tiny: NE of Th vs None on the semisphere (a test experiment)."""
from psbench.report.aggregates import fmt_num, group_mean, long_frame, lookup
from psbench.report.verdicts import NE_MARGIN, num, verdict

TITLE = "Tiny: NE of Th vs None"
AVERAGES = "Mean NE over the semisphere runs of the grid."
NOTES = "A test experiment."
THESIS = {"": {"Th": {"0": 1.5}}}
GATED = True
PREPARED = []


def prepare(root, scale):
    PREPARED.append((str(root), scale))


def aggregate(rows):
    recs = []
    group_mean(rows, ["mask", "noise"], "ne_mean", recs, lambda k: "", lambda k: k[0],
               lambda k: fmt_num(k[1]))
    return long_frame(recs)


def verdicts(agg, rows=None):
    a, b = lookup(agg, "", "None", "0.1"), lookup(agg, "", "Th", "0.1")
    have = a == a and b == b
    return [verdict("Th beats None at 10 % noise", (b < a) if have else None,
                    f"None {num(a)} / Th {num(b)} deg",
                    undecided=have and abs(a - b) < NE_MARGIN)]


def figures(agg):
    from psbench.report.figures import finish, line, new_figure

    fig, (ax,) = new_figure()
    for r in ("None", "Th"):
        line(ax, agg, "", r)
    finish(ax, "noise", "NE (deg)")
    return [("tiny", fig)]
'''

GRID = '''\
experiment:
  name: tiny
  description: "tiny test grid"
  grids:
    - {surface: [semisphere], mask: [None, Th], noise: [0.0, 0.1]}
  fixed: {lights: 45x8}
  scales:
    full: {size: 512}
    ci: {size: 24, seed: [0]}
'''


def _forget(prefix):
    for name in [m for m in sys.modules if m == prefix or m.startswith(prefix + ".")]:
        del sys.modules[name]


@pytest.fixture
def tiny(tmp_path):
    """Install package ``tinyexp`` (experiment ``tiny``) through a real entry point."""
    site = tmp_path / "site"
    pkg = site / "tinyexp"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "tiny.py").write_text(MODULE)
    (pkg / "tiny.yaml").write_text(GRID)
    info = site / "tinyexp-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: tinyexp\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[psbench.experiments]\ntiny = tinyexp.tiny\n")
    sys.path.insert(0, str(site))
    importlib.invalidate_caches()
    registry.reload("experiments")
    try:
        yield registry.get("experiments", "tiny")
    finally:
        sys.path.remove(str(site))
        _forget("tinyexp")
        importlib.invalidate_caches()
        registry.reload("experiments")


def test_entry_point_registers_module_and_grid(tiny):
    assert tiny.module.__name__ == "tinyexp.tiny"
    assert tiny.grid.name == "tiny.yaml" and tiny.TITLE == "Tiny: NE of Th vs None"
    names = T.names()
    builtin = set(registry._builtin("experiments"))           # psbench's own modules
    assert names[-1] == "tiny" and names[0] == "table2_1"
    assert sorted(names) == sorted(builtin | {"tiny"}) and len(builtin) >= 22
    assert "tiny" in gate.gated() and "table5_3" in gate.gated()


def test_command_line_runs_it_and_the_report_renders_it(tiny, tmp_path, capsys):
    root = tmp_path / "results"
    main(["+experiment=tiny", "scale=ci", "jobs=1", f"results_dir={root}"])
    df = read_store(root, experiment="tiny")
    assert len(df) == 4 and set(df["status"]) == {"ok"} and set(df["size"]) == {24}
    assert set(df["mask"]) == {"None", "Th"}
    assert tiny.module.PREPARED == [(str(root), "ci")]          # prepare ran before the runs
    main(["experiment=tiny", "scale=ci", "jobs=1", f"results_dir={root}"])   # no '+' too
    assert "4 of 4 runs skipped (stored)" in capsys.readouterr().err

    out = tmp_path / "reports"
    build(root, out, "ci", log=lambda *a: None, experiments=("tiny",))
    md = (out / "tiny.md").read_text()
    assert md.startswith("# Tiny: NE of Th vs None")
    assert "What psbench averages: Mean NE over the semisphere runs" in md
    assert "Deviations / caveats: A test experiment." in md
    assert "Th beats None at 10 % noise" in md and "Runs: 4 ok, 0 failed" in md
    # psbench | thesis | difference in separate columns
    assert re.search(r"\| Th \| \d+\.\d\d \| 1\.50 \| [+-]\d+\.\d\d \|", md)
    assert "name: tiny" in md                                    # its grid, shown verbatim
    assert (out / "figures" / "tiny.png").read_bytes()[:4] == b"\x89PNG"
    assert "tiny.html" in (out / "index.md").read_text()

    base = tmp_path / "baselines"
    assert gate.update(root, base, ("tiny",), out=lambda *a: None) == 0
    assert gate.check(root, base, ("tiny",), out=lambda *a: None) == 0


def test_register_at_run_time_and_clean_errors(tmp_path, capsys):
    (tmp_path / "adhoc_exp.py").write_text(MODULE.replace("GATED = True", "GATED = False"))
    (tmp_path / "adhoc_exp.yaml").write_text(GRID.replace("name: tiny", "name: adhoc_exp"))
    (tmp_path / "nogrid_exp.py").write_text(MODULE)
    sys.path.insert(0, str(tmp_path))
    try:
        mod = importlib.import_module("adhoc_exp")
        spec = registry.register("experiments", mod)
        assert spec.name == "adhoc_exp" and spec.grid == tmp_path / "adhoc_exp.yaml"
        assert "adhoc_exp" in T.names() and "adhoc_exp" not in gate.gated()
        registry.register("experiments", importlib.import_module("nogrid_exp"))
        with pytest.raises(SystemExit) as e:
            main(["+experiment=nogrid_exp", "scale=ci", f"results_dir={tmp_path / 'r'}"])
        assert e.value.code == 2 and "has no grid" in capsys.readouterr().err
        with pytest.raises(SystemExit) as e:
            main(["+experiment=adhoc_exp", "scale=huge", f"results_dir={tmp_path / 'r'}"])
        err = capsys.readouterr().err
        assert e.value.code == 2 and "scale='huge'" in err and "ci" in err
        assert mod.PREPARED == []                      # refused before prepare
    finally:
        sys.path.remove(str(tmp_path))
        for n in ("adhoc_exp", "nogrid_exp"):
            registry.unregister("experiments", n)
            _forget(n)
    with pytest.raises(SystemExit) as e:
        main(["+experiment=no_such_thing", f"results_dir={tmp_path / 'r'}"])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "no_such_thing" in err and "table5_3" in err
    assert not (tmp_path / "r" / "runs").exists()


def test_every_builtin_experiment_keeps_the_contract():
    from psbench.harness.grid import load

    names = [n for n in T.names() if n.startswith(("table", "fig"))]
    assert len(names) == 17
    names += ["interpretations", "chapter7"]
    for name in names:
        mod = T.experiment_module(name)
        assert isinstance(mod, types.ModuleType) and mod.__name__ == f"psbench.experiments.{name}"
        assert mod.TITLE and mod.AVERAGES and isinstance(mod.NOTES, str)
        assert isinstance(mod.THESIS, dict) and isinstance(mod.GATED, bool)
        assert callable(mod.aggregate) and callable(mod.verdicts)
        assert callable(getattr(mod, "figures", len))          # optional (Table 2.1 has none)
        exp = load(name, results_dir="/r")
        assert exp["name"] == name and exp["scales"].keys() >= {"full", "ci"}
    assert gate.gated() == ("table2_1", "table5_3", "table5_4", "table5_5", "table5_6",
                            "fig5_12", "chapter7", "robust", "stress")
    data = load("table6_1", results_dir="/r")["grids"][0]["data"]
    assert "/r/simrig/penny" in data or "PSBENCH_SIMRIG" in __import__("os").environ
