"""Compiled inner loops of :func:`psbench.render.shadowmap.shadow_map` (numba).

The two resampling steps of the horizon sweep stay with ``cv2.warpAffine``; these
kernels replace the numpy passes between them. They perform the same float
operations in the same order as the passes they replace (one add of the lift, a
running maximum, two adds and a comparison), so the maps are bit-identical to
the numpy formulation, and independent of the thread count (every output element
depends on its own column or pixel only).

They run on one thread (``parallel=False``): each is a few milliseconds of
memory-bound work between two multi-threaded ``cv2.warpAffine`` calls, and a second
thread pool (numba's) waking between OpenCV's costs more than it gains -- measured
~3x slower per light at 512 x 512 on two loaded cores, no gain at 2048 x 2048.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["lift_running_max", "above"]

#: working columns per parallel task (a block of one row stays in cache)
_BLOCK = 256


@njit(cache=True, nogil=True)
def lift_running_max(g, lift):
    """In place: ``g[w] += lift[w]``, then the running maximum of ``g`` along axis 0.

    Parameters
    ----------
    g : (L, n) float32 or float64, C-contiguous
    lift : (L,) same dtype as ``g``
    """
    L, n = g.shape
    nb = (n + _BLOCK - 1) // _BLOCK
    for blk in range(nb):
        lo = blk * _BLOCK
        hi = min(n, lo + _BLOCK)
        top = np.empty(hi - lo, g.dtype)  # running max of the block (keeps the loop SIMD)
        g0 = g[0, lo:hi]
        for j in range(hi - lo):
            top[j] = g0[j] + lift[0]
            g0[j] = top[j]
        for w in range(1, L):
            c = lift[w]
            gw = g[w, lo:hi]
            for j in range(hi - lo):
                m = max(top[j], gw[j] + c)  # no NaN here: heights are finite
                top[j] = m
                gw[j] = m
    return g


@njit(cache=True, nogil=True)
def above(horizon, hb, rowpart, colpart, out):
    """``out = horizon > (hb + rowpart[:, None]) + colpart[None, :]``, (H, W) bool."""
    H, W = horizon.shape
    for r in range(H):
        rp = rowpart[r]
        for c in range(W):
            out[r, c] = horizon[r, c] > (hb[r, c] + rp) + colpart[c]
    return out
