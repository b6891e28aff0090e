"""The harness's self-test run kind ``noop``, a plug-in the tests register.

``tests/conftest.py`` puts ``tests/plugins`` on ``sys.path`` and ``PYTHONPATH``; the
``psbench_selftest-0.1.dist-info`` beside this package declares the entry point
``psbench.run_kinds: noop``, so every process of a test (the ``psbench`` command, its
joblib / submitit workers) finds the kind as it finds an installed plug-in's.

``kind=noop`` computes nothing; its ``args`` drive the faults under test: ``sleep``
(seconds), ``fail`` (raise with this message), ``alloc_mb`` (allocate that much memory),
``die`` (SIGKILL the process running it, as the out-of-memory killer would). ``ne_mean``
is a number derived from the run id, so rows differ run by run.
"""
from __future__ import annotations

import os
import signal
import time

import numpy as np

from psbench.registry import RunKind


def noop(p, row):
    """Fill ``row`` of run ``p`` (normalized parameters) without computing anything."""
    a = p["args"]
    if a.get("sleep"):
        time.sleep(float(a["sleep"]))
    if a.get("fail"):
        raise RuntimeError(str(a["fail"]))
    if a.get("alloc_mb"):                  # memory exhaustion, for tests of limits
        row["payload"] = str(float(np.ones(int(float(a["alloc_mb"]) * 2**17)).sum()))
    if a.get("die"):                      # a run killed mid-way (OOM killer)
        os.kill(os.getpid(), signal.SIGKILL)
    row.update(ne_mean=float(int(row["run_id"][:4], 16) % 100) / 10.0)


RUN_KIND = RunKind("noop", noop, help="harness self-test (tests only): args sleep, fail, "
                   "alloc_mb, die")
