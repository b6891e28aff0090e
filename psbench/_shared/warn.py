"""psbench's warning categories and the one-line form the command-line tools print.

Python shows a warning with its file, line number and source line, which tells a user
of the ``psbench`` commands nothing; :func:`one_line` formats every warning as a single
``psbench: warning: ...`` line instead, and :func:`install` makes it the format of a
process (the console entry points and the pool workers call it). Library use keeps
Python's format (callers filter by category, e.g. :class:`ConvergenceWarning`).

:func:`install` also makes ``kill -USR2 <pid>`` print the stack of every thread of the
process to its standard error (:mod:`faulthandler`), so that a run that seems stuck
can say where it is without being stopped; forked run processes inherit it.
"""
from __future__ import annotations

import faulthandler
import signal
import sys
import warnings

__all__ = ["ConvergenceWarning", "one_line", "install"]


class ConvergenceWarning(RuntimeWarning):
    """Some pixels of a solve did not converge within the iteration limit; the message
    gives their count and the option that raises the limit."""


def one_line(message, category, filename, lineno, line=None) -> str:
    """``warnings.formatwarning`` replacement: one line, no source line."""
    text = " ".join(str(message).split())
    if category.__module__.split(".")[0] == "psbench" or "psbench" in str(filename):
        if issubclass(category, DeprecationWarning):
            return f"psbench: deprecated: {text}\n"
        return f"psbench: warning: {text}\n"
    return f"psbench: warning ({category.__name__} from {filename}:{lineno}): {text}\n"


def install() -> None:
    """Print the process's warnings as :func:`one_line` lines, and every thread's stack
    on SIGUSR2 (idempotent)."""
    warnings.formatwarning = one_line
    if hasattr(signal, "SIGUSR2"):
        try:
            faulthandler.register(signal.SIGUSR2, file=sys.stderr, all_threads=True)
        except (ValueError, OSError, AttributeError):   # no usable stderr (pythonw)
            pass
