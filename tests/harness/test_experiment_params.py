"""Run parameters an experiment does not honour are refused before any work."""
import os
import subprocess
import sys
from pathlib import Path

import pytest

_BIN = Path(sys.executable).parent / "psbench"


@pytest.mark.parametrize("arg,msg", [
    ("jobs=0", "jobs=0: expected -1"),
    ("sweep=x0", "sweep=x0: experiments store their rows in runs/table5_3/"),
    ("size=64", "size=64: experiment table5_3 sets size itself (scale=ci: 40)"),
])
def test_dropped_parameter_is_refused(tmp_path, arg, msg):
    env = {k: v for k, v in os.environ.items() if k != "PSBENCH_RESULTS"}
    r = subprocess.run([str(_BIN), "+experiment=table5_3", "scale=ci", arg, "results_dir=res"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and msg in lines[0], r.stderr
    assert not (tmp_path / "res" / "runs").exists()          # nothing computed or stored
