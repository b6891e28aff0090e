"""psbench's warnings: one line in psbench's words, with the count and the option."""
import subprocess
import sys
import warnings

from psbench._shared.warn import ConvergenceWarning, one_line


def test_one_line_has_no_source_line():
    text = one_line("tsfit: 3 of 100 object pixels did not converge\n  more", ConvergenceWarning,
                    "/x/psbench/solve/methods/tsfit.py", 12, line="return _tsfit(...)")
    assert text == "psbench: warning: tsfit: 3 of 100 object pixels did not converge more\n"
    other = one_line("boom", RuntimeWarning, "/x/numpy/core.py", 7, line="x = 1 / 0")
    assert other.count("\n") == 1 and "x = 1 / 0" not in other and "boom" in other


def test_cli_prints_non_convergence_as_one_line(tmp_path):
    code = ("import warnings, sys\n"
            "from psbench.harness.app import main\n"
            "main(['size=32', 'method=robust', 'options.n_iter=1', 'mask=None',"
            f" 'results_dir={tmp_path}', 'outputs=none'])\n")
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if "did not converge" in ln]
    assert lines, r.stderr
    for ln in lines:
        assert ln.startswith("psbench: warning: robust: ") and "options.n_iter" in ln, ln
    assert "warnings.warn" not in r.stderr and ".py:" not in r.stderr, r.stderr
