"""Compiled per-pixel comparison of two fits' held-out errors (see :mod:`psbench.solve.fallback`).

Layout: lights first, pixels last ((k, n) float32 held-out errors, uint8 evaluation
set); each pixel is independent (``prange`` over blocks of pixels). Inside a block the
loop runs light by light over the block's pixels (each pixel's sums still run over its
lights in order, and an observation outside the evaluation set adds an exact zero, so
the sums are the plain per-pixel ones); blocks of 4096 pixels read each light's row in
runs long enough to stream (96 x 45200, one thread: 20.8 ms pixel by pixel or in
blocks of 256, 9.7 ms).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

__all__ = ["paired", "BLOCK"]

#: pixels per prange task
BLOCK = 4096


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
        s = np.zeros(hi - lo)
        ss = np.zeros(hi - lo)
        cnt = np.zeros(hi - lo, dtype=np.int32)
        for i in range(k):
            iv = inv_sigma[i]
            for p in range(lo, hi):
                a = float(e_m[i, p]) * iv
                b = float(e_s[i, p]) * iv
                la = min(a * a, c2) if a == a else c2
                lb = min(b * b, c2) if b == b else c2
                d = la - lb
                use = E[i, p] != 0
                s[p - lo] += d if use else 0.0
                ss[p - lo] += d * d if use else 0.0
                cnt[p - lo] += np.int32(use)
        for p in range(lo, hi):
            c = cnt[p - lo]
            count[p] = c
            if c == 0:
                mean[p] = 0.0
                se[p] = math.inf
                continue
            m = s[p - lo] / c
            mean[p] = m
            if c < 2:
                se[p] = math.inf
            else:
                var = max(ss[p - lo] - c * m * m, 0.0) / (c - 1)
                se[p] = math.sqrt(var / c)
