"""Select numba's fork-safe threading layer before any psbench kernel runs.

numba's default threading layer on Linux is GNU OpenMP, which kills a process forked
after a parallel kernel ran ("fork() called from a process already using GNU OpenMP").
psbench's runs fork a child per chunk, so psbench selects numba's fork-safe
``workqueue`` layer unless the user chose one (``NUMBA_THREADING_LAYER``). That layer
must not launch parallel kernels from two Python threads at once; psbench never does.

It also locks numba's on-disk kernel cache (``cache=True``) across processes. Saving a
compiled signature reads the function's index (``*.nbi``: signature -> data file), picks
the first free data file number, writes the index, then the data, with no lock: two
processes compiling different signatures of one function at once (two pool workers, two
test workers on a fresh install) both pick ``*.1.nbc``, and the index can be left
filing one signature under the other's machine code, which a later process loads and
calls with the wrong argument types. An exclusive ``flock`` per index around a save and
a shared one around a load make each atomic; the compiled code is unchanged.
"""
from __future__ import annotations

import contextlib
import os
import sys

LAYER = "workqueue"


def select_layer() -> None:
    if "NUMBA_THREADING_LAYER" in os.environ:  # the user's choice
        return
    if "numba" in sys.modules:  # imported before psbench: its config is read already
        cfg = sys.modules["numba"].config
        if cfg.THREADING_LAYER == "default":
            cfg.THREADING_LAYER = LAYER
    else:  # numba reads it on import (and child processes inherit it)
        os.environ["NUMBA_THREADING_LAYER"] = LAYER


@contextlib.contextmanager
def _flock(index_path, exclusive):
    import fcntl

    try:                               # beside the index; a read-only cache goes unlocked
        fd = os.open(index_path + ".lock", os.O_RDWR | os.O_CREAT, 0o666)
    except OSError:
        fd = None
    if fd is None:
        yield
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH)
        yield
    finally:
        os.close(fd)                   # releases the lock


def lock_cache() -> bool:
    """Make numba's cache index updates atomic across processes (see the module's
    docstring). Returns False where it cannot (no ``fcntl``, another numba layout)."""
    try:
        import fcntl  # noqa: F401
        from numba.core.caching import IndexDataCacheFile as cls
    except ImportError:
        return False
    if getattr(cls, "_psbench_locked", False):
        return True
    if not (hasattr(cls, "save") and hasattr(cls, "load")):
        return False
    save, load = cls.save, cls.load

    def locked_save(self, key, data):
        with _flock(self._index_path, True):
            return save(self, key, data)

    def locked_load(self, key):
        with _flock(self._index_path, False):
            return load(self, key)

    cls.save, cls.load, cls._psbench_locked = locked_save, locked_load, True
    return True


select_layer()
lock_cache()
