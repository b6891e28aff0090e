"""Compiled per-pixel passes shared by masks (numba): the Lambert residual of Hi and CS,
and the angle test of Re.

Each replaces a (k, 3) x (3, n) float32 matrix product followed by a pass over the
(k, n) product: one pass, without the (k, n) temporary (256 MB at 2048 x 2048 x 16).
The 3-term dot products are contracted to fused multiply-adds where the CPU has them,
as BLAS does; the two can still round a product differently in the last bit, so a mask
decision exactly at its threshold may differ from the matrix-product formulation. Every
output depends on its own pixel only: any thread count gives the same result.

Pixels run on numba's threads (``prange``; psbench selects numba's fork-safe threading
layer, :mod:`psbench._shared.numba_setup`, so psbench's forked runs may use them).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["lambert_residuals", "within_cos"]


@njit(cache=True, nogil=True, parallel=True, fastmath={"contract"})
def lambert_residuals(images, b, S, out):
    """``out[i, p] = images[i, p] - S[i] . b[p]``; images (k, n), b (n, 3), S (k, 3)
    float32."""
    k, n = images.shape
    for p in prange(n):
        b0, b1, b2 = b[p, 0], b[p, 1], b[p, 2]
        for i in range(k):
            t = S[i, 0] * b0
            t = t + S[i, 1] * b1
            t = t + S[i, 2] * b2
            out[i, p] = images[i, p] - t
    return out


@njit(cache=True, nogil=True, parallel=True, fastmath={"contract"})
def within_cos(normals, H, c, out):
    """``out[i, p] = H[i] . normals[p] <= c[i]``; normals (n, 3), H (k, 3), c (k,)
    float32."""
    k = H.shape[0]
    n = normals.shape[0]
    for p in prange(n):
        n0, n1, n2 = normals[p, 0], normals[p, 1], normals[p, 2]
        for i in range(k):
            t = H[i, 0] * n0
            t = t + H[i, 1] * n1
            t = t + H[i, 2] * n2
            out[i, p] = t <= c[i]
    return out
