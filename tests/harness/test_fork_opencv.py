"""A run process forked after OpenCV ran in parallel in its supervisor does not hang.

A child forked while OpenCV's worker pool has threads inherits a pool without them,
and its next parallel call (the shadow maps' ``cv2.warpAffine``) can wait forever:
measured on 2 cores, 1-2 forks in 100-300, and a 6-run test sweep hung in its third run.
The supervisor stops the pool before each fork (``supervise._fork``).
"""
from __future__ import annotations

import subprocess
import sys

import pytest

cv2 = pytest.importorskip("cv2")

FORKS = r"""
import os, sys, time
import cv2, numpy as np
from psbench.harness.supervise import _opencv_pool_stopped, _opencv_threads
cv2.setNumThreads(2)
src = np.random.default_rng(0).random((400, 400), dtype=np.float32)
M = np.array([[0.9, 0.1, 3.0], [-0.1, 0.9, 2.0]])
def work():
    for _ in range(5):
        cv2.warpAffine(src, M, (400, 400), flags=cv2.INTER_LINEAR)
hung = 0
for _ in range(int(sys.argv[1])):
    work()                                 # the supervisor's pool is running
    n = _opencv_pool_stopped()
    pid = os.fork()
    if pid == 0:
        _opencv_threads(n)
        work()
        os._exit(0 if cv2.getNumThreads() == 2 else 3)
    _opencv_threads(n)
    t0 = time.time()
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            assert status == 0, status     # the child had its thread count back
            break
        if time.time() - t0 > 10:
            os.kill(pid, 9); os.waitpid(pid, 0); hung += 1
            break
        time.sleep(0.002)
print(hung, cv2.getNumThreads())
"""


def test_forked_children_run_opencv_in_parallel_without_hanging():
    out = subprocess.run([sys.executable, "-c", FORKS, "60"], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    hung, threads = out.stdout.split()
    assert hung == "0" and threads == "2", out.stdout      # and the supervisor's count back


SUPERVISED = r"""
import os, sys
import cv2, numpy as np
from psbench.harness.params import normalize
from psbench.harness.supervise import run_supervised
cv2.setNumThreads(2)
src = np.zeros((300, 300), np.float32)
cv2.warpAffine(src, np.eye(2, 3), (300, 300))       # the supervisor's pool has started
seen, real = [], os.fork
def fork():
    seen.append(cv2.getNumThreads())
    return real()
os.fork = fork
p = normalize({"surface": "spheres", "size": 24, "lights": "30x8"})
rows = run_supervised([p], root=sys.argv[1], sweep="s")
print(rows[0]["status"], seen, cv2.getNumThreads())
"""


def test_the_supervisor_forks_with_opencv_on_one_thread(tmp_path):
    """The run (its shadow maps call ``cv2.warpAffine``) is forked with the pool stopped,
    and the supervisor has its thread count back afterwards."""
    out = subprocess.run([sys.executable, "-c", SUPERVISED, str(tmp_path)], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["ok", "[1]", "2"], out.stdout


def test_without_opencv_loaded_nothing_is_touched(monkeypatch):
    from psbench.harness import supervise

    monkeypatch.delitem(sys.modules, "cv2")
    assert supervise._opencv_pool_stopped() is None
    supervise._opencv_threads(None)                         # no-op
