"""Compiled helpers of tsfit around the fit: the dark-observation test of the
weights and the neighbour statistics of the propagation.

Each replaces a chain of numpy temporaries over the (k, P) observations or the
(3, H, W) normals with one pass; every pixel is computed on its own, so results
do not depend on the number of threads.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ._tsfit_kernel import _DX, _DY, _DZ, _HX, _HY, _HZ, _MU, BLOCK, FASTMATH, _acos, _expm

__all__ = ["dark_weights", "neighbour_mean", "near"]

#: the 8-neighbourhood as (row, column) offsets
_DY8 = np.array([-1, -1, -1, 0, 0, 1, 1, 1])
_DX8 = np.array([-1, 0, 1, -1, 1, -1, 0, 1])


@njit(cache=True, parallel=True, nogil=True, fastmath=FASTMATH)
def dark_weights(tab, n, rd, rs, m, lobe, I, valid, margin, ratio, out):
    """out (k, P) bool: ``valid`` and not dark, where an observation is dark when the
    model predicts p > margin_i and I < ratio p and I < p - margin_i (float32, as
    the numpy form of :func:`psbench.solve.methods._tsstart.put_back`). The model is
    Lambert + Torrance–Sparrow (``lobe``) or Lambert alone (rs, m unused)."""
    k, P = I.shape
    nb = (P + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        lo, hi = blk * BLOCK, min(P, (blk + 1) * BLOCK)
        pr = np.empty(hi - lo, dtype=np.float32)
        for i in range(k):
            dx, dy, dz = tab[_DX, i], tab[_DY, i], tab[_DZ, i]
            hx, hy, hz, mu = tab[_HX, i], tab[_HY, i], tab[_HZ, i], tab[_MU, i]
            # the prediction in its own loop (one branch-free loop per model, so
            # each vectorises), then the test
            if lobe:
                for p in range(lo, hi):
                    nx, ny, nz = float(n[0, p]), float(n[1, p]), float(n[2, p])
                    c = dx * nx + dy * ny + dz * nz
                    ch = min(max(hx * nx + hy * ny + hz * nz, -1.0), 1.0)
                    th = _acos(ch)
                    v = float(rd[p]) * c + float(rs[p]) * _expm(float(m[p]) ** 2 * th * th)
                    pr[p - lo] = mu * v if c > 0.0 else 0.0
            else:
                for p in range(lo, hi):
                    c = dx * float(n[0, p]) + dy * float(n[1, p]) + dz * float(n[2, p])
                    pr[p - lo] = mu * float(rd[p]) * c if c > 0.0 else 0.0
            mg = margin[i]
            for p in range(lo, hi):
                v = pr[p - lo]
                x = I[i, p]
                dark = (x < ratio * v) & (x < v - mg) & (v > mg)
                out[i, p] = valid[i, p] & ~dark


@njit(cache=True, parallel=True, nogil=True)
def neighbour_mean(pos, flat, W2, n, fitted, mean, ang):
    """Mean normal of each fitted pixel's fitted 8-neighbours, normalised (3, P), and
    the angle (radians) between it and the pixel's normal (NaN where the pixel is
    not fitted or has no fitted neighbour). ``pos``: the padded grid's pixel index
    (-1 off the fitted object); ``flat`` (P,): each pixel's place in it; ``W2``:
    the padded width."""
    P = flat.shape[0]
    for p in prange(P):
        ax = np.float32(0.0)
        ay = np.float32(0.0)
        az = np.float32(0.0)
        if fitted[p]:
            for o in range(8):
                q = pos[flat[p] + _DY8[o] * W2 + _DX8[o]]
                if q >= 0:
                    ax += n[0, q]
                    ay += n[1, q]
                    az += n[2, q]
        nrm = math.sqrt(ax * ax + ay * ay + az * az)
        if fitted[p] and nrm > 0.0:
            mx, my, mz = ax / nrm, ay / nrm, az / nrm
            cs = mx * n[0, p] + my * n[1, p] + mz * n[2, p]
            ang[p] = math.acos(min(max(cs, -1.0), 1.0))
        else:
            mx = my = mz = math.nan
            ang[p] = math.nan
        mean[0, p], mean[1, p], mean[2, p] = mx, my, mz


@njit(cache=True, parallel=True, nogil=True)
def near(pos, flat, W2, changed, fitted, out):
    """out (P,) bool: fitted pixels with a changed pixel among their 8 neighbours."""
    P = flat.shape[0]
    for p in prange(P):
        hit = False
        if fitted[p]:
            for o in range(8):
                q = pos[flat[p] + _DY8[o] * W2 + _DX8[o]]
                if q >= 0 and changed[q]:
                    hit = True
        out[p] = hit
