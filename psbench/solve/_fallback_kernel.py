"""Compiled per-pixel comparison of two fits' held-out errors (see :mod:`psbench.solve.fallback`).

Layout: lights first, pixels last ((k, n) float32 held-out errors, uint8 evaluation
set); each pixel is independent (``prange`` over blocks of pixels).
"""
from __future__ import annotations

import math

from numba import njit, prange

__all__ = ["paired", "BLOCK"]

#: pixels per prange task
BLOCK = 256


@njit(cache=True, nogil=True, parallel=True)
def paired(e_m, e_s, E, inv_sigma, c2, mean, se, count):
    """Mean and standard error of d_i = l(e_m,i) - l(e_s,i) over the evaluation set.

    l(e) = min((e / sigma_i)^2, c2), NaN (an undefined held-out error) costing c2.
    e_m, e_s (k, n) float32; E (k, n) uint8 (1: in the evaluation set); inv_sigma (k,)
    float64; out: mean, se (n,) float64, count (n,) int32 (se = inf with fewer than 2
    observations)."""
    k, n = e_m.shape
    nb = (n + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        lo, hi = blk * BLOCK, min(n, (blk + 1) * BLOCK)
        for p in range(lo, hi):
            s = 0.0
            ss = 0.0
            c = 0
            for i in range(k):
                if E[i, p]:
                    a = float(e_m[i, p]) * inv_sigma[i]
                    b = float(e_s[i, p]) * inv_sigma[i]
                    la = min(a * a, c2) if a == a else c2
                    lb = min(b * b, c2) if b == b else c2
                    d = la - lb
                    s += d
                    ss += d * d
                    c += 1
            count[p] = c
            if c == 0:
                mean[p] = 0.0
                se[p] = math.inf
                continue
            m = s / c
            mean[p] = m
            if c < 2:
                se[p] = math.inf
            else:
                var = max(ss - c * m * m, 0.0) / (c - 1)
                se[p] = math.sqrt(var / c)
