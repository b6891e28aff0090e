"""psbench selects numba's fork-safe threading layer: a process that ran a parallel
kernel can still fork the children psbench's runs use."""
from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import os, sys
    import numpy as np
    import psbench  # noqa: F401  (selects the threading layer)
    from numba import njit, prange, threading_layer

    @njit(parallel=True)
    def twice(x):
        out = np.empty_like(x)
        for i in prange(x.size):
            out[i] = 2 * x[i]
        return out

    x = np.arange(100000.0)
    assert twice(x)[-1] == 2 * x[-1]
    pid = os.fork()
    if pid == 0:
        os._exit(0 if twice(x)[1] == 2.0 else 3)
    _, status = os.waitpid(pid, 0)
    print(threading_layer(), os.waitstatus_to_exitcode(status))
""")


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs fork")
def test_a_process_that_ran_a_parallel_kernel_can_fork():
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_THREADING_LAYER"}
    out = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    layer, child = out.stdout.split()
    assert layer == "workqueue"
    assert child == "0", out.stderr


def test_a_users_threading_layer_is_kept(monkeypatch):
    from psbench._shared import numba_setup as _numba_setup

    monkeypatch.setenv("NUMBA_THREADING_LAYER", "tbb")
    _numba_setup.select_layer()
    assert os.environ["NUMBA_THREADING_LAYER"] == "tbb"
