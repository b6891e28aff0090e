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
Inside a block the loops run light by light over the block's pixels, with the
per-pixel choices as selects, so that the pixel loop vectorises; every pixel's sums
still run over its lights in order, so the results do not depend on the block size
or the vector width (no fast-math: each value is the plain IEEE expression). An
observation a fit does not use is summed as an exact zero rather than skipped (a sum
that starts at +0 is never -0, so adding +-0 leaves it bit for bit as it was), which
keeps the loops free of conditional stores: they vectorise.

The median of a pixel's |e_i| (its validation error, :func:`abs_median`, and in the
same pass with the errors) is a bitwise selection, vectorised over the pixels: for
non-negative float32 values the order of the bit patterns as integers is the order of
the values, so the h-th smallest pattern is built bit by bit from the top (keep a bit
when at most h patterns lie below the candidate). It selects a value, never computes
one, so it is exactly the median ``np.nanmedian`` gives (an even count averages the two
middle values in float32).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numba.core import types
from numba.extending import intrinsic

from ._sym3 import HELDOUT_RCOND, inv_sym3
from .methods.tsfit._kernel import _acos, _expm, _light

__all__ = ["lambert_errors", "ts_errors", "abs_median", "LEVER"]

#: pixels per prange task (Torrance-Sparrow: its per-observation gradients are kept
#: for the block, 4 x (k, TS_BLOCK) float64)
BLOCK = 256
TS_BLOCK = 64
#: smallest 1 - h_i for which the held-out error is defined
LEVER = 1e-3
#: the bit pattern of a value left out of a median: above every finite float32 and inf
OUT = np.int32(0x7FFFFFFF)


@njit(cache=True, nogil=True, parallel=True)
def lambert_errors(I, S, w, out, med):
    """Held-out errors of the weighted Lambertian least-squares fit of each pixel.

    I (k, n) float32, S (k, 3) float64 (rows s_i = mu_i d_i), w (k, n) float32 or
    uint8 (>0: used); out (k, n) float32; med (n,) float32, or (0,) to skip it: the
    median |e_i| over the used, finite errors (as :func:`abs_median`, in the same
    pass). The fit is recomputed from ``w`` (it is the method's solution for the masks
    and the Lambertian robust solvers)."""
    k, n = I.shape
    nb = (n + BLOCK - 1) // BLOCK
    want = med.shape[0] > 0
    for blk in prange(nb):
        lo, hi = blk * BLOCK, min(n, (blk + 1) * BLOCK)
        B = hi - lo
        A = np.zeros((9, BLOCK))   # the normal matrix (6) and right-hand side (3)
        for i in range(k):
            sx, sy, sz = S[i, 0], S[i, 1], S[i, 2]
            for q in range(B):
                wi = float(w[i, lo + q])
                wu = wi if wi > 0.0 else 0.0   # unused: adds exact zeros (see above)
                v = wi * float(I[i, lo + q]) if wi > 0.0 else 0.0
                A[0, q] += wu * sx * sx
                A[1, q] += wu * sx * sy
                A[2, q] += wu * sx * sz
                A[3, q] += wu * sy * sy
                A[4, q] += wu * sy * sz
                A[5, q] += wu * sz * sz
                A[6, q] += v * sx
                A[7, q] += v * sy
                A[8, q] += v * sz
        X = np.empty((9, BLOCK))   # the inverse (6) and the solution (3)
        okv = np.empty(BLOCK, dtype=np.bool_)
        for q in range(B):
            b00, b01, b02, b11, b12, b22, ok = inv_sym3(A[0, q], A[1, q], A[2, q], A[3, q],
                                                         A[4, q], A[5, q], HELDOUT_RCOND)
            r0, r1, r2 = A[6, q], A[7, q], A[8, q]
            X[0, q], X[1, q], X[2, q], X[3, q], X[4, q], X[5, q] = b00, b01, b02, b11, b12, b22
            X[6, q] = b00 * r0 + b01 * r1 + b02 * r2
            X[7, q] = b01 * r0 + b11 * r1 + b12 * r2
            X[8, q] = b02 * r0 + b12 * r1 + b22 * r2
            okv[q] = ok
        U = np.empty((k, BLOCK), dtype=np.int32)   # |e_i| bit patterns for the median
        cnt = np.zeros(BLOCK, dtype=np.int32)
        for i in range(k):
            sx, sy, sz = S[i, 0], S[i, 1], S[i, 2]
            for q in range(B):
                p = lo + q
                r = float(I[i, p]) - (sx * X[6, q] + sy * X[7, q] + sz * X[8, q])
                wi = float(w[i, p])
                h = wi * (X[0, q] * sx * sx + X[3, q] * sy * sy + X[5, q] * sz * sz
                          + 2.0 * (X[1, q] * sx * sy + X[2, q] * sx * sz + X[4, q] * sy * sz))
                e = np.float32(r / (1.0 - h)) if 1.0 - h > LEVER else np.float32(np.nan)
                o = e if wi > 0.0 else np.float32(r)
                out[i, p] = o if okv[q] else np.float32(np.nan)
                _put(U, cnt, i, q, e, wi > 0.0 and okv[q])
        if want:
            _block_median(U, cnt, B, med, lo)


@njit(cache=True, nogil=True, parallel=True)
def ts_errors(tab, I, w, n, rd, rs, m, out, med):
    """Held-out errors of the Lambert + Torrance-Sparrow fit of each pixel, to first
    order in its per-pixel unknowns rho * n (rho_s and m held at their fitted values).

    tab (7, k) the light table of :func:`psbench.solve.methods.tsfit._kernel.tables`;
    I (k, n) float32; w (k, n) float32 or uint8; n (3, n) unit normals; rd, rs, m (n,)
    float32; out (k, n) float32; med (n,) float32 or (0,), as in :func:`lambert_errors`.
    The model's gradient in b = rho_d n is
    mu_i [d_i + (2 m^2 rho_s E_i theta_i / sin theta_i / rho_d) (h_i - (h_i . n) n)] on
    lit observations, 0 in self shadow (where the residual is the observation)."""
    k, P = I.shape
    nb = (P + TS_BLOCK - 1) // TS_BLOCK
    want = med.shape[0] > 0
    for blk in prange(nb):
        lo, hi = blk * TS_BLOCK, min(P, (blk + 1) * TS_BLOCK)
        B = hi - lo
        R = np.empty((k, TS_BLOCK))
        JX = np.empty((k, TS_BLOCK))   # the gradients of the observations
        JY = np.empty((k, TS_BLOCK))
        JZ = np.empty((k, TS_BLOCK))
        A = np.zeros((6, TS_BLOCK))
        kap = np.empty(TS_BLOCK)
        m2v = np.empty(TS_BLOCK)
        for q in range(B):
            rdp, rsp, m2 = float(rd[lo + q]), float(rs[lo + q]), float(m[lo + q]) ** 2
            kap[q] = 2.0 * m2 * rsp / rdp if rdp > 0.0 else 0.0
            m2v[q] = m2
        for i in range(k):
            dx, dy, dz, hx, hy, hz, mu = _light(tab, i)
            for q in range(B):
                p = lo + q
                nx, ny, nz = float(n[0, p]), float(n[1, p]), float(n[2, p])
                c = dx * nx + dy * ny + dz * nz
                wi = float(w[i, p])
                Iv = float(I[i, p])
                ch = min(max(hx * nx + hy * ny + hz * nz, -1.0), 1.0)
                th = _acos(ch)
                e = _expm(m2v[q] * th * th)
                lit = c > 0.0
                r = Iv - mu * (float(rd[p]) * c + float(rs[p]) * e)
                R[i, q] = r if lit else Iv
                sn = math.sqrt(max(1.0 - ch * ch, 0.0))
                bt = kap[q] * e * (th / sn if sn > 1e-6 else 1.0)
                use = lit and wi > 0.0   # the gradient of the observations fitted
                jx = mu * (dx + bt * (hx - ch * nx)) if use else 0.0
                jy = mu * (dy + bt * (hy - ch * ny)) if use else 0.0
                jz = mu * (dz + bt * (hz - ch * nz)) if use else 0.0
                JX[i, q] = jx
                JY[i, q] = jy
                JZ[i, q] = jz
                wu = wi if use else 0.0   # unused: adds exact zeros (see above)
                A[0, q] += wu * jx * jx
                A[1, q] += wu * jx * jy
                A[2, q] += wu * jx * jz
                A[3, q] += wu * jy * jy
                A[4, q] += wu * jy * jz
                A[5, q] += wu * jz * jz
        X = np.empty((6, TS_BLOCK))
        okv = np.empty(TS_BLOCK, dtype=np.bool_)
        for q in range(B):
            b00, b01, b02, b11, b12, b22, ok = inv_sym3(A[0, q], A[1, q], A[2, q], A[3, q],
                                                         A[4, q], A[5, q], HELDOUT_RCOND)
            X[0, q], X[1, q], X[2, q], X[3, q], X[4, q], X[5, q] = b00, b01, b02, b11, b12, b22
            okv[q] = ok
        U = np.empty((k, TS_BLOCK), dtype=np.int32)
        cnt = np.zeros(TS_BLOCK, dtype=np.int32)
        for i in range(k):
            for q in range(B):
                p = lo + q
                wi = float(w[i, p])
                jx, jy, jz = JX[i, q], JY[i, q], JZ[i, q]
                h = wi * (X[0, q] * jx * jx + X[3, q] * jy * jy + X[5, q] * jz * jz
                          + 2.0 * (X[1, q] * jx * jy + X[2, q] * jx * jz + X[4, q] * jy * jz))
                e = np.float32(R[i, q] / (1.0 - h)) if 1.0 - h > LEVER else np.float32(np.nan)
                e = e if okv[q] else np.float32(np.nan)
                out[i, p] = e if wi > 0.0 else np.float32(R[i, q])
                _put(U, cnt, i, q, e, wi > 0.0)
        if want:
            _block_median(U, cnt, B, med, lo)


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
        U = np.empty((k, BLOCK), dtype=np.int32)
        cnt = np.zeros(BLOCK, dtype=np.int32)
        for i in range(k):
            for q in range(hi - lo):
                _put(U, cnt, i, q, e[i, lo + q], used[i, lo + q] != 0)
        _block_median(U, cnt, hi - lo, out, lo)


@njit(cache=True, nogil=True, inline="always")
def _put(U, cnt, i, q, e, used):
    """Enter the bit pattern of |e| (float32) as pixel q's i-th candidate of its median
    when used and finite (else OUT), counting it (one store: the loop vectorises)."""
    good = used and math.isfinite(e)
    U[i, q] = _bits(abs(e)) if good else OUT
    cnt[q] += np.int32(good)


@intrinsic
def _bits(typingctx, x):
    """The int32 bit pattern of the float32 x (an LLVM bitcast)."""
    if x != types.float32:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.int32))
    return types.int32(types.float32), codegen


@njit(cache=True, nogil=True, inline="always")
def _block_median(U, cnt, B, med, lo):
    """med[lo + q] for q < B: the median of the cnt[q] non-negative float32 values whose
    bit patterns are the entries of U[:, q] below OUT (NaN if none; see the module
    docstring)."""
    k, nq = U.shape
    ans = np.zeros(nq, dtype=np.int32)
    h = np.empty(nq, dtype=np.int32)
    s = np.empty(nq, dtype=np.int32)
    for q in range(B):
        h[q] = cnt[q] // 2
    # the largest pattern a with #(U < a) <= h: the h-th smallest (0-based)
    for b in range(30, -1, -1):
        bit = np.int32(1 << b)
        for q in range(B):
            s[q] = 0
        for i in range(k):
            for q in range(B):
                s[q] += np.int32(U[i, q] < (ans[q] | bit))
        for q in range(B):
            if s[q] <= h[q]:
                ans[q] |= bit
    # an even count also needs the (h-1)-th: the largest pattern below, or a tie
    below = np.zeros(nq, dtype=np.int32)
    lo_u = np.zeros(nq, dtype=np.int32)
    for i in range(k):
        for q in range(B):
            u = U[i, q]
            lt = u < ans[q]
            below[q] += np.int32(lt)
            lo_u[q] = max(lo_u[q], u if lt else np.int32(0))
    hv, lv = ans.view(np.float32), lo_u.view(np.float32)
    for q in range(B):
        c = cnt[q]
        if c == 0:
            med[lo + q] = np.float32(np.nan)
        elif c % 2 == 1:
            med[lo + q] = hv[q]
        else:
            low = lv[q] if below[q] >= h[q] else hv[q]
            med[lo + q] = np.float32(low + hv[q]) / np.float32(2.0)
