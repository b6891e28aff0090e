"""Compiled passes of the masked Poisson CG (:func:`psbench.integrate.poisson._poisson_cg`).

Each replaces a chain of numpy passes over the (H, W) float64 grid with one pass and
performs the same float operations in the same order per element (no fastmath, so no
reassociation or fused multiply-adds): the heights are bit-identical to the numpy
formulation and independent of the thread count. The inner products stay with numpy
(their summation order decides the last bits of every later iterate).
"""
from __future__ import annotations

from numba import njit, prange

__all__ = ["laplacian", "step", "direction"]


@njit(cache=True, nogil=True, parallel=True)
def laplacian(z, wx, wy, out):
    """out (H, W): the in-mask edge Laplacian of z (wx (H, W-1), wy (H-1, W): 1 where
    the edge joins two object pixels); returns ``out``.

    With bx = (z[:, 1:] - z[:, :-1]) wx and by = (z[1:] - z[:-1]) wy, each element is
    ((-bx[i, j] or 0) + bx[i, j - 1]) - by[i, j] + by[i - 1, j], the terms present
    where the edge exists, added in that order."""
    H, W = z.shape
    for i in prange(H):
        for j in range(W):
            if j < W - 1:
                acc = -((z[i, j + 1] - z[i, j]) * wx[i, j])
            else:
                acc = 0.0
            if j >= 1:
                acc += (z[i, j] - z[i, j - 1]) * wx[i, j - 1]
            if i < H - 1:
                acc -= (z[i + 1, j] - z[i, j]) * wy[i, j]
            if i >= 1:
                acc += (z[i, j] - z[i - 1, j]) * wy[i - 1, j]
            out[i, j] = acc
    return out


@njit(cache=True, nogil=True, parallel=True)
def step(z, r, d, Ad, a):
    """In place: z += a d; Ad *= a; r -= Ad (a CG step, each rounded as numpy does)."""
    H, W = z.shape
    for i in prange(H):
        for j in range(W):
            z[i, j] += a * d[i, j]
            Ad[i, j] *= a
            r[i, j] -= Ad[i, j]


@njit(cache=True, nogil=True, parallel=True)
def direction(d, y, beta):
    """In place: d = d beta + y (the next search direction)."""
    H, W = d.shape
    for i in prange(H):
        for j in range(W):
            d[i, j] = d[i, j] * beta + y[i, j]
