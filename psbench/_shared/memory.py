"""How psbench's heavy calls get memory from the OS: plain pages, and freed memory kept.

Two policies hold while a solve, a render or an integration runs (:func:`managed_memory`;
nested and concurrent calls keep them until the last one returns); both leave every
array's values unchanged, only how its pages are obtained.

**Plain pages.** numpy advises the kernel to back every array of 4 MiB or more with transparent huge
pages (``madvise(MADV_HUGEPAGE)``). On Linux hosts whose huge-page defrag setting is
``madvise`` (``/sys/kernel/mm/transparent_hugepage/defrag``; the kernel's default
since Linux 4.6), the kernel then compacts memory synchronously at the first touch
of each 2 MiB page of such an array: on a host whose memory is fragmented the process
stalls in the kernel. The solvers allocate and drop many (k, n) temporaries of tens of megabytes,
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

numpy's advice is turned off during the call and restored afterwards (numpy's own
switch, ``numpy._core.multiarray._set_madvise_hugepage``). The user's choice wins: with
``NUMPY_MADVISE_HUGEPAGE`` set in the environment psbench leaves numpy's setting alone.

**Freed memory kept.** glibc's malloc hands every block above its mmap threshold (at
most 32 MiB) to the OS when it is freed, so the next array of that size is a fresh
mapping whose every 4 KiB page faults and is zeroed at first touch. A 2048 x 2048
float64 array is 33.5 MiB: the integrator's conjugate-gradient steps and the masks'
(k, H, W) stacks allocate such arrays again and again. Measured on a 2-core AVX2 VM:
filling a fresh 33.5 MiB array took 21 ms against 2.5 ms for one already mapped, and
the 2048^2 forensic pipeline (``benchmarks/forensic_pipeline.py --compare``, 3
alternating runs per tree) spent 5.9 s against 0.6 s in its final integration. On
glibc (Linux), during the call malloc serves every block from its heap (``mallopt(M_MMAP_MAX, 0)``) and keeps what is freed
(``M_TRIM_THRESHOLD`` 2 GiB); at the end it leaves the thresholds where glibc's own
dynamic rule leaves them once a 32 MiB block has been freed (mmap threshold 32 MiB, trim
threshold 64 MiB). Peak memory rises a little, as the heap's free blocks fragment
(2048^2 pipeline: 2.05 GiB against 1.92). What the call freed stays with the process for the
next call instead of being handed back at once: glibc returns the heap's top beyond
64 MiB at a later free, and ``malloc_trim(0)`` (``ctypes.CDLL("libc.so.6")``) returns the
rest. The whole pipeline took 26.2 s without this policy and 15.4 s with it (medians,
same session); returning everything at the end of every call (``malloc_trim(0)``)
was slower (24.2 s against 19.7 s in two back-to-back measurements on a busier host),
because each stage then faulted its memory in again. The user's choice wins: with
``GLIBC_TUNABLES`` naming a malloc tunable, or any ``MALLOC_*_`` variable, set, psbench
leaves malloc alone; elsewhere (macOS, Windows, musl) it does nothing.
"""
from __future__ import annotations

import ctypes
import functools
import os
import platform
import sys
import threading

import numpy as np

__all__ = ["managed_memory"]

_lock = threading.Lock()
_depth = 0
_saved = None

#: mallopt parameters (malloc.h) and the values set during a call and after it
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD, M_MMAP_MAX = -1, -3, -4
KEEP_TRIM = 2 ** 31 - 1          # mallopt takes a C int
AFTER = ((M_MMAP_MAX, 65536), (M_MMAP_THRESHOLD, 32 << 20), (M_TRIM_THRESHOLD, 64 << 20))


def _switch():
    """numpy's huge-page switch (None where this numpy has none)."""
    core = getattr(np, "_core", None) or getattr(np, "core", None)
    return getattr(getattr(core, "multiarray", None), "_set_madvise_hugepage", None)


def _malloc():
    """glibc's C library (None off glibc, or where the user tuned malloc)."""
    if sys.platform != "linux" or platform.libc_ver()[0] != "glibc":
        return None
    if "malloc" in os.environ.get("GLIBC_TUNABLES", "") or any(
            k.startswith("MALLOC_") and k.endswith("_") for k in os.environ):
        return None
    try:
        libc = ctypes.CDLL("libc.so.6")
        libc.mallopt.argtypes = [ctypes.c_int] * 2
    except (OSError, AttributeError):
        return None
    return libc


def _enter():
    global _depth, _saved
    with _lock:
        _depth += 1
        if _depth == 1:
            if _SET is not None:
                _saved = _SET(False)
            if _LIBC is not None:
                _LIBC.mallopt(M_MMAP_MAX, 0)
                _LIBC.mallopt(M_TRIM_THRESHOLD, KEEP_TRIM)


def _exit():
    global _depth, _saved
    with _lock:
        _depth -= 1
        if _depth == 0:
            if _saved is not None:
                _SET(_saved)
                _saved = None
            if _LIBC is not None:
                for param, value in AFTER:
                    _LIBC.mallopt(param, value)


_SET = None if "NUMPY_MADVISE_HUGEPAGE" in os.environ else _switch()
_LIBC = _malloc()


def managed_memory(func):
    """Decorator: run ``func`` under psbench's memory policies (see the module
    docstring); a no-op where neither applies (the user chose both, or the platform
    has neither)."""
    if _SET is None and _LIBC is None:
        return func

    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        _enter()
        try:
            return func(*args, **kwargs)
        finally:
            _exit()

    return wrapper
