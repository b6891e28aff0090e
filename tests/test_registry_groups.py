"""Analyses, forensic recipes and run kinds from outside psbench: registered at run time
and through a real entry point, then found where psbench's own are (``kind=analysis``,
the forensic study's method labels, ``kind=<name>``)."""
import json
import sys
import textwrap
from pathlib import Path

import pytest

from psbench import registry
from psbench._shared.checks import PsbenchError
from psbench.forensic import pipeline
from psbench.harness import run as R
from psbench.harness import choices as C


def ring_count(lights="45x8", *, scale=1.0):
    """Images of the layout, times ``scale``."""
    from psbench.lights import layout

    return {"k": layout(lights).k * scale}


@pytest.fixture
def runtime_pieces():
    registry.register("analyses", ring_count)
    registry.register("recipes", registry.Recipe("half Th", {"mask": "Th", "method": "ps"}))
    yield
    registry.unregister("analyses", "ring_count")
    registry.unregister("recipes", "half Th")


def test_builtins_are_registered():
    assert {"ne_vs_surface_zenith", "wps_table", "forensic"} <= set(registry.analyses())
    assert list(registry.recipes())[:5] == ["None", "Th-Hi-Re-Sh", "weighted Th-Hi-Re-Sh",
                                            "weighted Th-Hi-Re-Sh (um)", "WPS"]
    assert pipeline.recipes()["WPS"] == {"method": "wps"}


def test_runtime_analysis_runs_as_kind_analysis(runtime_pieces):
    assert "ring_count" in C.analyses()
    row = R.execute(R.normalize({"kind": "analysis", "analysis": "ring_count",
                                 "lights": "30x8+60x8", "args": {"scale": 2.0}}))
    assert row["status"] == "ok", row.get("error")
    assert json.loads(row["payload"]) == {"k": 32.0}


def test_unknown_analysis_lists_registered_ones(runtime_pieces):
    with pytest.raises(PsbenchError, match="ring_count"):
        R.validate(R.normalize({"kind": "analysis", "analysis": "nope"}))


def test_runtime_recipe_in_the_study(runtime_pieces):
    assert pipeline.solve_kwargs("half Th", 4.9) == {"mask": "Th", "method": "ps"}
    assert "half Th" not in pipeline.RECIPES          # psbench's own table is not edited
    with pytest.raises(PsbenchError, match="half Th"):
        pipeline.solve_kwargs("nope", 4.9)


def test_old_names_warn():
    with pytest.warns(DeprecationWarning, match="RECIPES"):
        assert pipeline.METHODS is pipeline.RECIPES
    with pytest.warns(DeprecationWarning, match="RUN_KINDS"):
        assert R.KINDS == ("solve", "cond", "analysis")


# ------------------------------------------------------------- a real entry point
PLUGIN = '''
from psbench.registry import Recipe, RunKind


def doubled(x=1.0):
    """Twice x."""
    return {"x2": 2 * x}


RECIPE = Recipe("plain L1", {"method": "l1"}, help="L1 without masks")


def constant(p, row):
    row["ne_mean"] = float(p["seed"])


RUN_KIND = RunKind("constant", constant, params=("seed",))
'''


@pytest.fixture
def entry_point_package(tmp_path):
    (tmp_path / "psb_demo_pieces.py").write_text(textwrap.dedent(PLUGIN))
    info = tmp_path / "psb_demo_pieces-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: psb-demo-pieces\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[psbench.analyses]\ndoubled = psb_demo_pieces:doubled\n\n"
        "[psbench.recipes]\nplain_l1 = psb_demo_pieces:RECIPE\n\n"
        "[psbench.run_kinds]\nconstant = psb_demo_pieces:RUN_KIND\n")
    sys.path.insert(0, str(tmp_path))
    registry.reload()
    yield
    sys.path.remove(str(tmp_path))
    sys.modules.pop("psb_demo_pieces", None)
    registry.reload()


def test_entry_point_pieces(entry_point_package):
    assert registry.analyses()["doubled"].help == "Twice x."
    row = R.execute(R.normalize({"kind": "analysis", "analysis": "doubled", "args": {"x": 3}}))
    assert json.loads(row["payload"]) == {"x2": 6}
    assert pipeline.solve_kwargs("plain L1", 4.9) == {"method": "l1"}
    p = R.normalize({"kind": "constant", "seed": 7, "surface": "spheres", "size": 64})
    assert p["surface"] is None and p["size"] is None     # not read by this kind
    row = R.execute(p)
    assert row["status"] == "ok" and row["ne_mean"] == 7.0


def test_entry_point_pieces_gone_after_reload():
    assert "doubled" not in registry.analyses() and "plain L1" not in registry.recipes()
    with pytest.raises(PsbenchError, match="kind='constant' is not known"):
        R.normalize({"kind": "constant"})


def test_selftest_kind_is_a_plugin_of_the_tests():
    """``noop`` is not part of psbench: the tests' plug-in registers it by entry point."""
    pkg = Path(R.__file__).resolve().parents[1]
    assert not [p for p in pkg.rglob("*.py") if '"noop"' in p.read_text()]
    assert registry.run_kinds()["noop"].func.__module__ == "psbench_selftest"
