"""The ``psbench`` command in a subprocess, for the harness tests.

A command that does not finish in time is asked for its stacks (SIGUSR2: every
process of its tree prints where each thread is, see ``psbench._shared.warn``) before
it is killed, and the test fails with them: a hang says where it hung.
"""
from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

_BIN = Path(sys.executable).parent / "psbench"
CMD = [str(_BIN)] if _BIN.exists() else [sys.executable, "-m", "psbench.harness.app"]


def clean_env(**extra):
    """This process's environment without the variables that redirect psbench."""
    env = {k: v for k, v in os.environ.items() if k not in ("PSBENCH_RESULTS", "HYDRA_FULL_ERROR")}
    env.update(extra)
    return env


def _tree(pid):
    try:
        import psutil
    except ImportError:
        return [pid]
    with contextlib.suppress(psutil.Error):
        return [pid] + [c.pid for c in psutil.Process(pid).children(recursive=True)]
    return [pid]


def communicate(proc, *, timeout, what):
    """``proc.communicate(timeout=)``; on a timeout, the stacks of every process of its
    tree (SIGUSR2), then all of them killed and the test failed with the stacks."""
    try:
        return proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        pids = _tree(proc.pid)
        for pid in pids:                       # one at a time: their dumps do not interleave
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGUSR2)
            time.sleep(0.5)
        for pid in pids:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"{what} did not finish in {timeout} s (processes {pids}); its stderr "
                    f"and stacks:\n{err[-8000:]}")


def run_psbench(*args, cwd, timeout, env=None, **kw):
    """``subprocess.run(CMD + args)`` with text output captured; a timeout fails the test
    with the stacks of every process of the command."""
    proc = subprocess.Popen(CMD + list(args), cwd=cwd, env=clean_env() if env is None else env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)
    out, err = communicate(proc, timeout=timeout, what=f"psbench {' '.join(args)}")
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)
