"""Compiled pieces of Eq. 3.1's completion rule (:class:`psbench.solve._engine._Completer`).

Per-pixel loops (numba) in place of numpy passes over (k, n) arrays whose axis 0 is
the light: the per-pixel counts of valid observations, a stable sort of each pixel's
residual magnitudes, and the fill of the missing observations. Same results as
``valid.sum(axis=0)``, ``np.argsort(r, axis=0, kind="stable")`` and the vectorised
fill; every column is handled on its own, so any thread count gives the same result.

Pixels run on numba's threads (``prange``; psbench selects numba's fork-safe threading
layer, :mod:`psbench._shared.numba_setup`, so psbench's forked runs may use them).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["short_columns", "order", "fill"]

#: above this many lights the insertion sort (O(k^2) per pixel) gives way to numpy's
_INSERTION_MAX = 32


@njit(cache=True, nogil=True)
def _counts(valid, out):
    k, n = valid.shape
    for j in range(n):
        c = 0
        for i in range(k):
            c += valid[i, j]
        out[j] = c
    return out


def short_columns(valid):
    """Columns of ``valid`` (k, n) bool with fewer than three True, and their counts."""
    cnt = _counts(valid, np.empty(valid.shape[1], dtype=np.int32))
    short = np.flatnonzero(cnt < 3)
    return short, cnt[short]


def order(r, dtype):
    """``np.argsort(r, axis=0, kind="stable")`` as ``dtype``, (k, n)."""
    if r.shape[0] > _INSERTION_MAX:
        return np.argsort(r, axis=0, kind="stable").astype(dtype)
    return _stable_order(r, np.empty(r.shape, dtype=dtype))


@njit(cache=True, nogil=True, parallel=True)
def _stable_order(r, out):
    """``out[:, j] = argsort(r[:, j], kind="stable")`` for every column (NaN last).

    Parameters
    ----------
    r : (k, n) float
    out : (k, n) integer
    """
    k, n = r.shape
    for j in prange(n):
        idx = np.empty(k, dtype=np.int64)
        key = np.empty(k, dtype=r.dtype)
        for i in range(k):  # insertion sort: moves only strictly greater keys (stable)
            v = r[i, j]
            p = i
            while p > 0 and (key[p - 1] > v or (np.isnan(key[p - 1]) and not np.isnan(v))):
                key[p] = key[p - 1]
                idx[p] = idx[p - 1]
                p -= 1
            key[p] = v
            idx[p] = i
        for i in range(k):
            out[i, j] = idx[i]
    return out


@njit(cache=True, nogil=True)
def fill(valid, short, counts, order):
    """In place: for column ``short[s]`` of ``valid`` (k, n), set the observations
    ``order[:, s]`` (best first) until three are True; ``counts[s]`` are its counts."""
    k = valid.shape[0]
    for s in range(short.size):
        j = short[s]
        c = counts[s]
        for t in range(k):
            if c >= 3:
                break
            i = order[t, s]
            if not valid[i, j]:
                valid[i, j] = True
                c += 1
    return valid
