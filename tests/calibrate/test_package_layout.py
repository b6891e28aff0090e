"""calibrate is maths / folder steps / command, above io; io never imports calibrate (the\nCalibration record and its application live in io._calibration)."""
from __future__ import annotations

import ast
import subprocess
import sys
from importlib import metadata
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[2] / "psbench"


def _imports(path, module):
    """Absolute names of the psbench modules a file imports (top level or in functions)."""
    parts = module.split(".")
    base = parts if path.name == "__init__.py" else parts[:-1]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            root = base[:len(base) - node.level + 1] if node.level else []
            mod = ".".join(root + ([node.module] if node.module else []))
            out.add(mod)
            out |= {f"{mod}.{a.name}" for a in node.names}
    return {m for m in out if m.startswith("psbench")}


def _module(path):
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def test_io_does_not_import_calibrate():
    for path in (PKG / "io").glob("*.py"):
        used = {m for m in _imports(path, _module(path)) if m.startswith("psbench.calibrate")}
        assert used == set(), path


def test_calibration_maths_does_no_io():
    name = "_fit.py"
    path = PKG / "calibrate" / name
    used = _imports(path, _module(path))
    # the record and the corrections it applies come from io._calibration; nothing else of io
    assert not {m for m in used if m.startswith(("psbench.io", "psbench.calibrate._steps",
                                                 "psbench.calibrate._cli",
                                                 "psbench._shared.files"))
                and not m.startswith("psbench.io._calibration")}
    src = path.read_text()
    for call in ("open(", "np.save", "np.load", "imread", "imwrite", "json."):
        assert call not in src, f"{name} calls {call}"


def _loaded_after(stmt):
    code = f"import sys; {stmt}; print(' '.join(sorted(m for m in sys.modules if m.startswith('psbench'))))"
    return set(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                              check=True).stdout.split())


def test_runtime_imports_are_one_way():
    io_mods = _loaded_after("import psbench.io")
    assert not {m for m in io_mods if m.startswith("psbench.calibrate")}
    cal_mods = _loaded_after("import psbench.calibrate")
    assert {"psbench.io", "psbench.calibrate._steps", "psbench.calibrate._cli"} <= cal_mods


def test_one_calibration_record():
    import psbench.calibrate as cal
    import psbench.io as io
    from psbench.io import _calibration
    assert cal.Calibration is _calibration.Calibration
    assert cal.apply_calibration is _calibration.apply_calibration
    assert cal.load_calibration is io.load_calibration


def test_command_entry_point_unchanged():
    eps = {e.name: e for e in metadata.entry_points(group="console_scripts")}
    if "psbench-calibrate" not in eps:
        pytest.skip("psbench is not installed (no console scripts)")
    ep = eps["psbench-calibrate"]
    assert ep.value == "psbench.calibrate:main"
    from psbench.calibrate import main
    assert ep.load() is main


def test_command_runs_as_a_program(tmp_path):
    out = subprocess.run([sys.executable, "-c", "import sys; from psbench.calibrate import main;"
                          " sys.exit(main(sys.argv[1:]))", "show", str(tmp_path)],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "no calibration.json" in out.stderr
