"""Compiled held-out prediction errors of one fit per pixel (see :mod:`psbench.solve.validation`).

Per pixel the fit's normal matrix A = sum_i w_i J_i J_i^T (3 x 3) is accumulated once;
leaving observation i out of the fit is a rank-1 downdate of A, and by the
Sherman-Morrison identity the prediction error of the refit without i is

    e_i = r_i / (1 - h_i),   h_i = w_i J_i^T A^{-1} J_i,

with r_i the residual of the full fit (exact for weighted linear least squares,
Lambert; to first order for a non-linear fit, Torrance-Sparrow, whose J_i is the
gradient of the model in rho * n). An observation the fit did not use (w_i = 0) is
already held out: e_i = r_i. NaN where the pixel's system is singular or i carried the
whole fit of a direction (1 - h_i <= ``LEVER``).

Layout: lights first, pixels last ((k, n) float32 observations and weights); each
pixel is independent (``prange`` over blocks of pixels; no reduction across pixels).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ._sym3 import HELDOUT_RCOND, inv_sym3
from .methods.tsfit._kernel import _acos, _expm, _light

__all__ = ["lambert_errors", "ts_errors", "abs_median", "LEVER"]

#: pixels per prange task
BLOCK = 256
#: smallest 1 - h_i for which the held-out error is defined
LEVER = 1e-3


@njit(cache=True, nogil=True, parallel=True)
def lambert_errors(I, S, w, out):
    """Held-out errors of the weighted Lambertian least-squares fit of each pixel.

    I (k, n) float32, S (k, 3) float64 (rows s_i = mu_i d_i), w (k, n) float32 or
    uint8 (>0: used); out (k, n) float32. The fit is recomputed from ``w`` (it is the
    method's solution for the masks and the Lambertian robust solvers)."""
    k, n = I.shape
    nb = (n + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        lo, hi = blk * BLOCK, min(n, (blk + 1) * BLOCK)
        for p in range(lo, hi):
            a00 = a01 = a02 = a11 = a12 = a22 = 0.0
            r0 = r1 = r2 = 0.0
            for i in range(k):
                wi = float(w[i, p])
                if wi > 0.0:
                    sx, sy, sz = S[i, 0], S[i, 1], S[i, 2]
                    v = wi * float(I[i, p])
                    a00 += wi * sx * sx
                    a01 += wi * sx * sy
                    a02 += wi * sx * sz
                    a11 += wi * sy * sy
                    a12 += wi * sy * sz
                    a22 += wi * sz * sz
                    r0 += v * sx
                    r1 += v * sy
                    r2 += v * sz
            b00, b01, b02, b11, b12, b22, ok = inv_sym3(a00, a01, a02, a11, a12, a22,
                                                              HELDOUT_RCOND)
            if not ok:
                for i in range(k):
                    out[i, p] = np.nan
                continue
            bx = b00 * r0 + b01 * r1 + b02 * r2
            by = b01 * r0 + b11 * r1 + b12 * r2
            bz = b02 * r0 + b12 * r1 + b22 * r2
            for i in range(k):
                sx, sy, sz = S[i, 0], S[i, 1], S[i, 2]
                r = float(I[i, p]) - (sx * bx + sy * by + sz * bz)
                wi = float(w[i, p])
                if wi > 0.0:
                    h = wi * (b00 * sx * sx + b11 * sy * sy + b22 * sz * sz
                              + 2.0 * (b01 * sx * sy + b02 * sx * sz + b12 * sy * sz))
                    out[i, p] = r / (1.0 - h) if 1.0 - h > LEVER else np.nan
                else:
                    out[i, p] = r


@njit(cache=True, nogil=True, parallel=True)
def ts_errors(tab, I, w, n, rd, rs, m, out):
    """Held-out errors of the Lambert + Torrance-Sparrow fit of each pixel, to first
    order in its per-pixel unknowns rho * n (rho_s and m held at their fitted values).

    tab (7, k) the light table of :func:`psbench.solve.methods.tsfit._kernel.tables`;
    I (k, n) float32; w (k, n) float32 or uint8; n (3, n) unit normals; rd, rs, m (n,)
    float32; out (k, n) float32. The model's gradient in b = rho_d n is
    mu_i [d_i + (2 m^2 rho_s E_i theta_i / sin theta_i / rho_d) (h_i - (h_i . n) n)] on
    lit observations, 0 in self shadow."""
    k, P = I.shape
    nb = (P + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        lo, hi = blk * BLOCK, min(P, (blk + 1) * BLOCK)
        J = np.empty((k, 3))
        R = np.empty(k)
        for p in range(lo, hi):
            nx, ny, nz = float(n[0, p]), float(n[1, p]), float(n[2, p])
            rdp, rsp, m2 = float(rd[p]), float(rs[p]), float(m[p]) ** 2
            kap = 2.0 * m2 * rsp / rdp if rdp > 0.0 else 0.0
            a00 = a01 = a02 = a11 = a12 = a22 = 0.0
            for i in range(k):
                dx, dy, dz, hx, hy, hz, mu = _light(tab, i)
                c = dx * nx + dy * ny + dz * nz
                wi = float(w[i, p])
                if c <= 0.0:    # self shadow: the model is 0 and so is its gradient
                    R[i] = float(I[i, p])
                    J[i, 0], J[i, 1], J[i, 2] = 0.0, 0.0, 0.0
                    continue
                ch = min(max(hx * nx + hy * ny + hz * nz, -1.0), 1.0)
                th = _acos(ch)
                e = _expm(m2 * th * th)
                R[i] = float(I[i, p]) - mu * (rdp * c + rsp * e)
                if wi > 0.0:    # the gradient is needed for the observations fitted
                    sn = math.sqrt(max(1.0 - ch * ch, 0.0))
                    bt = kap * e * (th / sn if sn > 1e-6 else 1.0)
                    jx = mu * (dx + bt * (hx - ch * nx))
                    jy = mu * (dy + bt * (hy - ch * ny))
                    jz = mu * (dz + bt * (hz - ch * nz))
                else:
                    jx = jy = jz = 0.0
                J[i, 0], J[i, 1], J[i, 2] = jx, jy, jz
                if wi > 0.0:
                    a00 += wi * jx * jx
                    a01 += wi * jx * jy
                    a02 += wi * jx * jz
                    a11 += wi * jy * jy
                    a12 += wi * jy * jz
                    a22 += wi * jz * jz
            b00, b01, b02, b11, b12, b22, ok = inv_sym3(a00, a01, a02, a11, a12, a22,
                                                              HELDOUT_RCOND)
            for i in range(k):
                wi = float(w[i, p])
                if wi > 0.0:
                    if not ok:
                        out[i, p] = np.nan
                        continue
                    jx, jy, jz = J[i, 0], J[i, 1], J[i, 2]
                    h = wi * (b00 * jx * jx + b11 * jy * jy + b22 * jz * jz
                              + 2.0 * (b01 * jx * jy + b02 * jx * jz + b12 * jy * jz))
                    out[i, p] = R[i] / (1.0 - h) if 1.0 - h > LEVER else np.nan
                else:
                    out[i, p] = R[i]


@njit(cache=True, nogil=True, parallel=True)
def abs_median(e, used, out):
    """Median of |e_i| over each pixel's used, finite held-out errors; NaN where none.

    e (k, n) float32; used (k, n) uint8 or bool; out (n,) float32. Bit for bit
    ``np.nanmedian`` of the same values (an even count averages the two middle values
    in float32), without its masked-array sort of the whole (k, n) block."""
    k, n = e.shape
    nb = (n + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        lo, hi = blk * BLOCK, min(n, (blk + 1) * BLOCK)
        # gather light by light (rows are contiguous in pixels), select pixel by pixel
        bufs = np.empty((hi - lo, k), dtype=np.float32)
        cnt = np.zeros(hi - lo, dtype=np.int64)
        for i in range(k):
            for p in range(lo, hi):
                v = e[i, p]
                if used[i, p] and math.isfinite(v):
                    bufs[p - lo, cnt[p - lo]] = abs(v)
                    cnt[p - lo] += 1
        for p in range(lo, hi):
            buf = bufs[p - lo]
            c = cnt[p - lo]
            if c == 0:
                out[p] = np.nan
                continue
            h = c // 2
            hi_v = _select(buf, c, h)
            if c % 2 == 1:
                out[p] = hi_v
            else:
                lo_v = buf[0]  # after the selection buf[:h] holds the h smallest
                for i in range(1, h):
                    if buf[i] > lo_v:
                        lo_v = buf[i]
                out[p] = np.float32(lo_v + hi_v) / np.float32(2.0)


@njit(cache=True, nogil=True, inline="always")
def _select(a, c, h):
    """The h-th smallest of a[:c] (0-based), partitioning a[:c] in place so that a[:h]
    holds the h smallest (Hoare's selection; a value is selected, never computed)."""
    lo, hi = 0, c - 1
    while lo < hi:
        mid = (lo + hi) // 2
        # median of three as the pivot
        if a[mid] < a[lo]:
            a[mid], a[lo] = a[lo], a[mid]
        if a[hi] < a[lo]:
            a[hi], a[lo] = a[lo], a[hi]
        if a[hi] < a[mid]:
            a[hi], a[mid] = a[mid], a[hi]
        pivot = a[mid]
        i, j = lo, hi
        while i <= j:
            while a[i] < pivot:
                i += 1
            while a[j] > pivot:
                j -= 1
            if i <= j:
                a[i], a[j] = a[j], a[i]
                i += 1
                j -= 1
        if h <= j:
            hi = j
        elif h >= i:
            lo = i
        else:
            return a[h]
    return a[h]
