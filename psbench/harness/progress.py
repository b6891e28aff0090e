"""A one-line progress display on stderr: runs done/total, failures, rate, ETA."""
from __future__ import annotations

import sys
import time

__all__ = ["Progress"]


def _hms(s):
    if s is None or s != s or s == float("inf"):
        return "?"
    s = int(round(s))
    h, r = divmod(s, 3600)
    m, s = divmod(r, 60)
    return f"{h:d}:{m:02d}:{s:02d}" if h else f"{m:d}:{s:02d}"


class Progress:
    """Track and display progress of ``total`` runs.

    The line is rewritten in place (``\\r``) when stderr is a terminal, otherwise
    printed at most every ``interval`` seconds; :meth:`close` prints a summary line.
    """

    def __init__(self, total, *, label="runs", stream=None, interval=None, skipped=0):
        self.total, self.label, self.skipped = int(total), label, int(skipped)
        self.stream = stream if stream is not None else sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.interval = interval if interval is not None else (0.2 if self.tty else 10.0)
        self.done = self.failed = 0
        self.t0 = time.perf_counter()
        self._last = -1e9
        self._width = 0

    def update(self, n=1, failed=0):
        self.done += n
        self.failed += failed
        self._show()

    def _line(self):
        el = time.perf_counter() - self.t0
        rate = self.done / el if el > 0 else 0.0
        eta = (self.total - self.done) / rate if rate > 0 else None
        fail = f", {self.failed} failed" if self.failed else ""
        return (f"{self.label}: {self.done}/{self.total} done{fail} | {rate:.2f} runs/s | "
                f"elapsed {_hms(el)} | ETA {_hms(eta if self.done < self.total else 0)}")

    def _show(self, force=False):
        now = time.perf_counter()
        if not force and now - self._last < self.interval and self.done < self.total:
            return
        self._last = now
        line = self._line()
        if self.tty:
            pad = max(0, self._width - len(line))
            self.stream.write("\r" + line + " " * pad)
            self._width = len(line)
        else:
            self.stream.write(line + "\n")
        self.stream.flush()

    def close(self):
        el = time.perf_counter() - self.t0
        if self.tty:
            self.stream.write("\n")
        rate = self.done / el if el > 0 else 0.0
        self.stream.write(f"{self.label}: {self.done - self.failed} ok, {self.failed} failed, "
                          f"{self.skipped} skipped (stored), {self.done + self.skipped} of "
                          f"{self.total + self.skipped} in {_hms(el)} ({rate:.2f} runs/s)\n")
        self.stream.flush()
