"""Select numba's fork-safe threading layer before any psbench kernel runs.

numba's default threading layer on Linux is GNU OpenMP, which kills a process forked
after a parallel kernel ran ("fork() called from a process already using GNU OpenMP").
psbench's runs fork a child per chunk, so psbench selects numba's fork-safe
``workqueue`` layer unless the user chose one (``NUMBA_THREADING_LAYER``). That layer
must not launch parallel kernels from two Python threads at once; psbench never does.
"""
from __future__ import annotations

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


select_layer()
