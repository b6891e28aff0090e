"""How psbench's solvers ask the OS for memory: plain pages, not numpy's huge-page advice.

numpy advises the kernel to back every array of 4 MiB or more with transparent huge
pages (``madvise(MADV_HUGEPAGE)``). On Linux hosts whose huge-page defrag setting is
``madvise`` (``/sys/kernel/mm/transparent_hugepage/defrag``; the kernel's default
since Linux 4.6), the kernel then compacts memory synchronously at the first touch
of each 2 MiB page of such an array: on a host whose memory is fragmented the process stalls in the
kernel. The solvers allocate and drop many (k, n) temporaries of tens of megabytes,
so they pay it on every solve. Measured on a 2-core AVX2 VM (defrag ``madvise``; one
thread, 96 images, medians of 3 fresh processes, ``benchmarks/hugepages.py``), wall
time of a process's first and second solve, numpy's advice -> plain pages:

======  ======  ==================  ==================
object  method  first solve, s      second solve, s
======  ======  ==================  ==================
cat     robust  5.47 -> 2.57        3.71 -> 2.53
cat     tsfit   7.62 -> 4.19        5.32 -> 4.06
bear    robust  4.71 -> 2.39        3.29 -> 2.24
bear    tsfit   7.17 -> 4.30        5.44 -> 4.21
======  ======  ==================  ==================

User CPU time is the same either way (2.06 vs 2.21 s, cat robust, first solve); the
difference is system time (2.66 vs 0.28 s) and time stalled (plain pages take 5x the
page faults, each cheap).

:func:`plain_pages` turns numpy's advice off while a solve runs and restores it
afterwards (numpy's own switch, ``numpy._core.multiarray._set_madvise_hugepage``;
nested and concurrent calls keep it off until the last one returns). Arrays are
unchanged: only how their pages are mapped. The user's choice wins: with
``NUMPY_MADVISE_HUGEPAGE`` set in the environment psbench leaves numpy's setting alone.
"""
from __future__ import annotations

import functools
import os
import threading

import numpy as np

__all__ = ["plain_pages"]

_lock = threading.Lock()
_depth = 0
_saved = None


def _switch():
    """numpy's huge-page switch (None where this numpy has none)."""
    core = getattr(np, "_core", None) or getattr(np, "core", None)
    return getattr(getattr(core, "multiarray", None), "_set_madvise_hugepage", None)


def _enter():
    global _depth, _saved
    with _lock:
        _depth += 1
        if _depth == 1:
            _saved = _SET(False)


def _exit():
    global _depth, _saved
    with _lock:
        _depth -= 1
        if _depth == 0 and _saved is not None:
            _SET(_saved)
            _saved = None


_SET = None if "NUMPY_MADVISE_HUGEPAGE" in os.environ else _switch()


def plain_pages(func):
    """Decorator: run ``func`` with numpy's huge-page advice off (see the module
    docstring); a no-op where the user set ``NUMPY_MADVISE_HUGEPAGE`` or numpy has no
    such switch."""
    if _SET is None:
        return func

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        _enter()
        try:
            return func(*args, **kwargs)
        finally:
            _exit()

    return wrapper
