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


# Two processes compile different signatures of one cached function at once. Each waits,
# between reading numba's cache index and writing it back, until the other got as far
# (at most WAIT[lock] s): without psbench's lock both read the empty index and both file their
# signature under the first data file, so one entry is lost (and that file may hold the
# other signature's code); with it the second cannot read the index before the first
# has written it.
WAIT = {"lock": 10, "nolock": 60}   # with the lock the first waits in vain
RACE = textwrap.dedent("""
    import os, sys, time
    from numba.core import caching
    here, lock, kind = sys.argv[1:4]
    if lock == "lock":
        import psbench  # noqa: F401  (locks the cache)
    write = caching.IndexDataCacheFile._save_index

    def wait_for_the_other(self, overloads):
        open(os.path.join(here, kind + ".saving"), "w").close()
        other = os.path.join(here, ("float" if kind == "int" else "int") + ".saving")
        t0 = time.time()
        while not os.path.exists(other) and time.time() - t0 < float(sys.argv[4]):
            time.sleep(0.05)
        write(self, overloads)

    caching.IndexDataCacheFile._save_index = wait_for_the_other
    sys.path.insert(0, here)
    import racy
    racy.twice(1 if kind == "int" else 1.5)
""")
CHECK = textwrap.dedent("""
    import pickle, sys
    from pathlib import Path
    import numba  # noqa: F401  (types for unpickling)
    sys.path.insert(0, sys.argv[2])
    nbi, = Path(sys.argv[1]).rglob("racy.twice-*.nbi")
    with open(nbi, "rb") as f:
        pickle.load(f)
        overloads = pickle.loads(f.read())[1]
    for key, name in overloads.items():
        data = pickle.loads((nbi.parent / name).read_bytes())
        assert data[3].args == key[0], (key[0], data[3])
    print(len(overloads))
""")


@pytest.mark.parametrize("lock", ["lock", "nolock"])
def test_concurrent_compiles_keep_every_signature(tmp_path, lock):
    (tmp_path / "racy.py").write_text(
        "from numba import njit\n\n@njit(cache=True)\ndef twice(x):\n    return 2 * x\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    procs = [subprocess.Popen([sys.executable, "-c", RACE, str(tmp_path), lock, kind,
                               str(WAIT[lock])],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for kind in ("int", "float")]
    for p in procs:
        assert p.wait(timeout=300) == 0, p.stderr.read()
    out = subprocess.run([sys.executable, "-c", CHECK, str(tmp_path / "cache"), str(tmp_path)], env=env,
                         capture_output=True, text=True, timeout=300)
    if lock == "lock":
        assert out.returncode == 0, out.stderr
        assert out.stdout.split() == ["2"]
    else:   # the race this guards against is real: numba alone loses a signature
        assert out.returncode != 0 or out.stdout.split() == ["1"], out.stdout
