"""Compiled helpers of tsfit around the fit -- the dark-observation test of the
weights and the neighbour statistics of the propagation -- and the residuals of
``robust``'s choice between its two fits.

Each replaces a chain of numpy temporaries over the (k, P) observations or the
(3, H, W) normals with one pass; every pixel is computed on its own, so results
do not depend on the number of threads.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ._kernel import _DX, _DY, _DZ, _MU, BLOCK, FASTMATH, _light, _model

__all__ = ["dark_weights", "dark_weights_pred", "neighbour_mean", "near", "choice_losses", "choice_sample",
           "row_middles"]

#: the 8-neighbourhood as (row, column) offsets
_DY8 = np.array([-1, -1, -1, 0, 0, 1, 1, 1])
_DX8 = np.array([-1, 0, 1, -1, 1, -1, 0, 1])


@njit(cache=True, parallel=True, nogil=True, fastmath=FASTMATH)
def dark_weights(tab, n, rd, rs, m, lobe, I, valid, margin, ratio, out):
    """out (k, P) bool: ``valid`` and not dark, where an observation is dark when the
    model predicts p > margin_i and I < ratio p and I < p - margin_i (float32, as
    the numpy form of :func:`psbench.solve.methods.tsfit._start.put_back`). The model is
    Lambert + Torrance–Sparrow (``lobe``) or Lambert alone (rs, m unused).

    One task per light, each along its whole row (every observation is tested on its
    own): runs of 256 pixels per light, as before, made it 3-8x slower (96 x 45200,
    one thread)."""
    k, P = I.shape
    for i in prange(k):
        lt = _light(tab, i)
        dx, dy, dz, mu = tab[_DX, i], tab[_DY, i], tab[_DZ, i], tab[_MU, i]
        mg = margin[i]
        # one branch-free loop per model, so that each vectorises
        if lobe:
            for p in range(P):
                v = np.float32(_model(lt, float(n[0, p]), float(n[1, p]), float(n[2, p]),
                                      float(rd[p]), float(rs[p]), float(m[p]) ** 2))
                out[i, p] = _not_dark(I[i, p], v, mg, ratio, valid[i, p])
        else:
            for p in range(P):
                c = dx * float(n[0, p]) + dy * float(n[1, p]) + dz * float(n[2, p])
                v = np.float32(mu * float(rd[p]) * c if c > 0.0 else 0.0)
                out[i, p] = _not_dark(I[i, p], v, mg, ratio, valid[i, p])


@njit(cache=True, nogil=True, inline="always")
def _not_dark(x, v, mg, ratio, valid):
    """An observation x (float32) is kept when valid and not dark under the prediction
    v (float32): dark when v > mg and x < ratio v and x < v - mg (float32)."""
    return valid & ~((x < ratio * v) & (x < v - mg) & (v > mg))


@njit(cache=True, parallel=True, nogil=True)
def dark_weights_pred(pred, I, valid, margin, ratio, out):
    """:func:`dark_weights` from the model's prediction pred (k, P) float32 when the
    caller already has it (the same test, the same float32 values; a task per light)."""
    k, P = I.shape
    for i in prange(k):
        mg = margin[i]
        for p in range(P):
            out[i, p] = _not_dark(I[i, p], pred[i, p], mg, ratio, valid[i, p])


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


@njit(cache=True, nogil=True, fastmath=FASTMATH, inline="always")
def _choice_residuals(lt, nx, ny, nz, rho, rs, m2, lx, ly, lz, x):
    """The residuals (Torrance-Sparrow fit, Lambertian fit) of one observation x under
    the two fits of :func:`choice_losses`."""
    dx, dy, dz, _, _, _, mu = lt
    return (x - _model(lt, nx, ny, nz, rho, rs, m2),
            x - mu * (dx * lx + dy * ly + dz * lz))


@njit(cache=True, parallel=True, nogil=True, fastmath=FASTMATH)
def choice_losses(tab, bt, rs, m, bl, I, V, all_valid, cap, loss_t, loss_l):
    """Truncated losses sum_i min(r_i^2, cap) over the valid observations of the two
    fits ``robust`` chooses between, (P,) each.

    bt (3, P): rho_d n of the Lambert + Torrance–Sparrow fit, with rho_s, m (P,);
    bl (3, P): rho n of the Lambertian fit (its residual is not clamped in self
    shadow: it is a plain least-squares fit); I, V (k, P) (V unused when
    ``all_valid``). Lights outer, pixels inner (the pixel loop vectorises)."""
    k, P = I.shape
    nb = (P + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        lo, hi = blk * BLOCK, min(P, (blk + 1) * BLOCK)
        nrm = np.empty((4, hi - lo))  # the unit normal and rho_d of the TS fit
        for p in range(lo, hi):
            bx, by, bz = float(bt[0, p]), float(bt[1, p]), float(bt[2, p])
            rho = math.sqrt(bx * bx + by * by + bz * bz)
            s = 1.0 / max(rho, 1e-30)
            nrm[0, p - lo], nrm[1, p - lo], nrm[2, p - lo] = bx * s, by * s, bz * s
            nrm[3, p - lo] = rho
            loss_t[p] = 0.0
            loss_l[p] = 0.0
        rt = np.empty(hi - lo)
        rl = np.empty(hi - lo)
        for i in range(k):
            lt = _light(tab, i)
            for p in range(lo, hi):
                j = p - lo
                r, q = _choice_residuals(lt, nrm[0, j], nrm[1, j], nrm[2, j], nrm[3, j],
                                         float(rs[p]), float(m[p]) ** 2, float(bl[0, p]),
                                         float(bl[1, p]), float(bl[2, p]), float(I[i, p]))
                rt[j] = min(r * r, cap)
                rl[j] = min(q * q, cap)
            if all_valid:
                for p in range(lo, hi):
                    loss_t[p] += rt[p - lo]
                    loss_l[p] += rl[p - lo]
            else:
                for p in range(lo, hi):
                    if V[i, p]:
                        loss_t[p] += rt[p - lo]
                        loss_l[p] += rl[p - lo]


@njit(cache=True, parallel=True, nogil=True, fastmath=FASTMATH)
def choice_sample(tab, bt, rs, m, bl, I, V, all_valid, pix, abs_t, abs_l):
    """|residual| of the two fits of :func:`choice_losses` at the pixels ``pix``, into
    abs_t, abs_l (k, len(pix)) float32 (NaN where not valid)."""
    k = I.shape[0]
    Q = pix.shape[0]
    nb = (Q + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        for j in range(blk * BLOCK, min(Q, (blk + 1) * BLOCK)):
            p = pix[j]
            bx, by, bz = float(bt[0, p]), float(bt[1, p]), float(bt[2, p])
            rho = math.sqrt(bx * bx + by * by + bz * bz)
            s = 1.0 / max(rho, 1e-30)
            for i in range(k):
                r, q = _choice_residuals(_light(tab, i), bx * s, by * s, bz * s, rho,
                                         float(rs[p]), float(m[p]) ** 2, float(bl[0, p]),
                                         float(bl[1, p]), float(bl[2, p]), float(I[i, p]))
                ok = all_valid or V[i, p]
                abs_t[i, j] = abs(r) if ok else math.nan
                abs_l[i, j] = abs(q) if ok else math.nan


#: the top bits of a non-negative float32's pattern that :func:`row_middles` counts
#: first (8 exponent bits and the top 3 of the mantissa: 2048 bins)
_SHIFT = 20
_ABS = np.int32(0x7FFFFFFF)
_INF = np.int32(0x7F800000)


@njit(cache=True, parallel=True, nogil=True)
def row_middles(u, keep, out):
    """The two middle order statistics of each row's kept values, for its median.

    u (k, P) int32: the bit patterns of non-negative float32 values (``x.view(int32)``;
    a -0 counts as 0); keep (k, P) bool. out (k, 4) int32 per row: the pattern of the
    (c // 2)-th smallest kept value (0-based), of the (c // 2 - 1)-th (the same for
    c = 1), the count c, and 1 if a kept value is NaN.

    For non-negative float32 the order of the patterns as integers is the order of
    the values, so a count of the top 11 bits finds the bin holding the middle, a
    count of the next 10 bits of that bin's values the sub-bin, and only the
    sub-bin's few values are sorted: the values selected are exactly those
    ``np.median`` averages (its partition of a gathered copy of each row was most of
    tsfit's noise-scale estimate). The count is branch-free (a value not kept counts
    in a spare bin) into 4 interleaved histograms, so that neighbouring values in one
    bin do not wait for each other."""
    k, P = u.shape
    nbin = (1 << (31 - _SHIFT)) + 1
    for i in prange(k):
        hist = np.zeros((4, nbin), dtype=np.int64)
        nan = np.int32(0)
        for p in range(P):
            v = u[i, p] & _ABS
            kp = keep[i, p]
            hist[p & 3, (v >> _SHIFT) if kp else nbin - 1] += 1
            nan |= np.int32(kp & (v > _INF))
        tot = hist.sum(0)
        c = P - tot[nbin - 1]
        out[i, 2], out[i, 3] = c, nan
        if c == 0 or nan:
            out[i, 0] = out[i, 1] = 0
            continue
        h = c // 2
        b, r1 = _rank_bin(tot, h)
        buf = np.empty(tot[b], dtype=np.int32)
        j = 0
        for p in range(P):
            v = u[i, p] & _ABS
            if (v >> _SHIFT) == b and keep[i, p]:    # rarely true: predicted
                buf[j] = v
                j += 1
        low = (buf >> (_SHIFT - 10)) & 1023
        sub = np.zeros(1024, dtype=np.int64)
        for q in range(j):
            sub[low[q]] += 1
        b2, r = _rank_bin(sub, r1)
        fin = buf[low == b2]
        fin.sort()
        out[i, 0] = fin[r]
        if r >= 1 or h == 0:
            out[i, 1] = fin[r - 1] if r >= 1 else fin[r]
        elif r1 >= 1:    # the largest of the bin's lower sub-bins
            out[i, 1] = buf[low < b2].max()
        else:   # the middle is its bin's smallest: the one below is in a lower bin
            lower = np.int32(-1)
            for p in range(P):
                v = u[i, p] & _ABS
                if keep[i, p] and (v >> _SHIFT) < b and v > lower:
                    lower = v
            out[i, 1] = lower


@njit(cache=True, nogil=True, inline="always")
def _rank_bin(hist, h):
    """The bin of a histogram holding the h-th smallest (0-based) and h's rank in it."""
    below = 0
    b = 0
    while below + hist[b] <= h:
        below += hist[b]
        b += 1
    return b, h - below
