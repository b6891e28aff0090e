"""Compiled per-pixel kernels of WPS (:mod:`psbench.solve.methods.wps`).

One pass over the images solves every ring, measures its residual, weighs the rings and
fuses them (Eqs. 4.3-4.16); the ring outputs come from the same pass or, on demand,
from a pass that only solves the rings. Pixels are processed in blocks of
:data:`BLOCK`, :data:`TASK` blocks per parallel task: within a block the loops over
pixels are innermost, so they compile to SIMD code, and the block's images stay in
cache between the ring solves and their residuals. Arithmetic
is float64 per pixel, outputs are float32. Every pixel is computed on its own (no
cross-pixel reduction, fixed blocks), so results do not depend on the thread count.

The surface-zenith sigmoid needs arccos and exp per pixel: both are inline
(:mod:`psbench.solve.methods.wps._math`), so the pixel loops stay SIMD.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ._math import DEG, acos, sig

__all__ = ["BLOCK", "KIND_NONE", "KIND_E", "KIND_ORACLE", "plain_rings", "ring_solutions",
           "weigh_rings"]

#: pixels per block (16 images x 256 pixels float32 = 16 kB stay in L1)
BLOCK = 256
#: blocks per parallel task (its scratch arrays are allocated once per task)
TASK = 16

# weight kinds: "None" (shares n_j / k), the e-family (Eqs. 4.13-4.16), the oracle
KIND_NONE, KIND_E, KIND_ORACLE = 0, 1, 2
# outputs of a pass: fused and ring outputs, the fused ones only, the ring ones only
_ALL, _FUSED, _RINGS = 0, 1, 2

@njit(cache=True, nogil=True, error_model="numpy")
def _solve_block(I2, lo, n, order, start, P, G, B, E2):
    """b_j = P_j I_j of every ring (B (R, 3, BLOCK)) and its mean squared residual e_j^2
    (E2 (R, BLOCK)) for the block's n pixels from ``lo``.

    The residual comes from the same pass, ``|I_j - S_j b_j|^2 = |I_j|^2 - b_j^T G_j
    b_j`` (S_j^T I_j = G_j b_j): in float64 its cancellation costs ~1e-16 |I_j|^2,
    below the float32 resolution of the images themselves. Lights are taken four at a
    time so that the accumulators are loaded and stored once per four images.
    """
    R = B.shape[0]
    for j in range(R):
        bx, by, bz, ss = B[j, 0], B[j, 1], B[j, 2], E2[j]
        bx[:n] = 0.0
        by[:n] = 0.0
        bz[:n] = 0.0
        ss[:n] = 0.0
        m = start[j]
        while m + 4 <= start[j + 1]:
            ia, ib, ic, id = order[m], order[m + 1], order[m + 2], order[m + 3]
            xa, xb = I2[ia, lo:lo + n], I2[ib, lo:lo + n]
            xc, xd = I2[ic, lo:lo + n], I2[id, lo:lo + n]
            a0, a1, a2 = P[ia, 0], P[ia, 1], P[ia, 2]
            b0, b1, b2 = P[ib, 0], P[ib, 1], P[ib, 2]
            c0, c1, c2 = P[ic, 0], P[ic, 1], P[ic, 2]
            d0, d1, d2 = P[id, 0], P[id, 1], P[id, 2]
            for q in range(n):
                va, vb = np.float64(xa[q]), np.float64(xb[q])
                vc, vd = np.float64(xc[q]), np.float64(xd[q])
                bx[q] += a0 * va + b0 * vb + c0 * vc + d0 * vd
                by[q] += a1 * va + b1 * vb + c1 * vc + d1 * vd
                bz[q] += a2 * va + b2 * vb + c2 * vc + d2 * vd
                ss[q] += va * va + vb * vb + vc * vc + vd * vd
            m += 4
        while m < start[j + 1]:
            ia = order[m]
            xa = I2[ia, lo:lo + n]
            a0, a1, a2 = P[ia, 0], P[ia, 1], P[ia, 2]
            for q in range(n):
                va = np.float64(xa[q])
                bx[q] += a0 * va
                by[q] += a1 * va
                bz[q] += a2 * va
                ss[q] += va * va
            m += 1
        cnt = start[j + 1] - start[j]
        if cnt == 3:        # exactly determined: no residual
            ss[:n] = 0.0
            continue
        g = G[j]
        g00, g01, g02, g11, g12, g22 = g[0, 0], g[0, 1], g[0, 2], g[1, 1], g[1, 2], g[2, 2]
        inv = 1.0 / cnt
        for q in range(n):
            x, y, z = bx[q], by[q], bz[q]
            fit = (x * (g00 * x + 2.0 * (g01 * y + g02 * z))
                   + y * (g11 * y + 2.0 * g12 * z) + g22 * z * z)
            ss[q] = max(ss[q] - fit, 0.0) * inv


@njit(cache=True, nogil=True, error_model="numpy")
def _e_weights(B, E2, INV, U, s, n, src, surf, sinz, rank, inv_zscale, binary):
    """Eqs. 4.13-4.16: u_j = factors_j / e_j^2, normalised (or one-hot), into U."""
    R = B.shape[0]
    for j in range(R):
        bz, e2, inv, u = B[j, 2], E2[j], INV[j], U[j]
        f = sinz[j] if src else 1.0
        for q in range(n):
            u[q] = f / (e2[q] + 1e-30)
        if surf:
            # surface zenith of the ring's own normal, sigmoid of the mirrored argument
            t = rank[j]
            for q in range(n):
                nz = min(max(bz[q] * inv[q], -1.0), 1.0)
                z = acos(nz) * (DEG * inv_zscale)
                u[q] *= sig((1.0 - t) * z + t * (1.0 - z))
    if binary:
        _one_hot(U, n, s[0], s[1])
        return
    tot = s[0]
    tot[:n] = 0.0
    for j in range(R):
        u = U[j]
        for q in range(n):
            tot[q] += u[q]
    for j in range(R):
        u = U[j]
        for q in range(n):
            u[q] = np.float32(u[q] / tot[q])


@njit(cache=True, nogil=True, error_model="numpy")
def _one_hot(U, n, best, pick):
    """Eq. 4.12: 1 at the first maximum of each pixel's weights (ties: the earlier ring;
    a NaN stops the search, as numpy's running maximum does). Rings in the outer loop,
    pixels inner (selects, no branches: SIMD); ``best`` and ``pick`` are scratch (n,)."""
    R = U.shape[0]
    u0 = U[0]
    for q in range(n):
        best[q] = u0[q]
        pick[q] = 0.0
    for j in range(1, R):
        u = U[j]
        for q in range(n):
            v = u[q]
            gt = v > best[q]
            pick[q] = j if gt else pick[q]
            best[q] = v if (gt or v != v) else best[q]
    for j in range(R):
        u = U[j]
        for q in range(n):
            u[q] = 1.0 if pick[q] == j else 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _oracle(B, RHO, INV, T, lo, U, n, pairs, tris, binary):
    """Oracle weights (module docs of ``wps``): per pixel the direction of the cone of
    the ring normals closest to the truth, as weights of the b_j. Candidates (best
    single normal, best point of each arc, the truth inside a cone of three) are
    evaluated for the whole block at once and kept where they are better. (Its scratch
    is allocated here: rows of one array given by the caller measured ~35 % slower.)"""
    R = B.shape[0]
    NN = np.empty((R, 3, BLOCK))
    CS = np.empty((R, BLOCK))
    C = U                       # direction coefficients, turned into weights at the end
    tr = np.empty((3, BLOCK))
    bc = np.empty(BLOCK)        # cosine of the best direction so far
    upd = np.empty(BLOCK)       # 1.0 where the candidate replaces it
    c1 = np.empty(BLOCK)
    c2 = np.empty(BLOCK)
    c3 = np.empty(BLOCK)
    tx, ty, tz = tr[0], tr[1], tr[2]
    t = T.reshape(-1)[3 * lo:3 * (lo + n)]
    for q in range(n):
        r0, r1, r2 = np.float64(t[3 * q]), np.float64(t[3 * q + 1]), np.float64(t[3 * q + 2])
        rn = max(math.sqrt(r0 * r0 + r1 * r1 + r2 * r2), 1e-30)
        tx[q] = r0 / rn
        ty[q] = r1 / rn
        tz[q] = r2 / rn
    for j in range(R):
        bx, by, bz, inv, cs = B[j, 0], B[j, 1], B[j, 2], INV[j], CS[j]
        nx, ny, nz = NN[j, 0], NN[j, 1], NN[j, 2]
        for q in range(n):
            nx[q] = bx[q] * inv[q]
            ny[q] = by[q] * inv[q]
            nz[q] = bz[q] * inv[q]
            cs[q] = nx[q] * tx[q] + ny[q] * ty[q] + nz[q] * tz[q]
    # best single ring normal (the first on ties)
    pick = c1
    for q in range(n):
        bc[q] = CS[0, q]
        pick[q] = 0.0
    for j in range(1, R):
        cs = CS[j]
        for q in range(n):
            gt = cs[q] > bc[q]
            pick[q] = j if gt else pick[q]
            bc[q] = cs[q] if gt else bc[q]
    for j in range(R):
        cj = C[j]
        for q in range(n):
            cj[q] = 1.0 if pick[q] == j else 0.0
    if not binary:
        for m in range(pairs.shape[0]):   # the best point of the arc between two normals
            i, j = pairs[m, 0], pairs[m, 1]
            a1, a2 = CS[i], CS[j]
            ix, iy, iz, jx, jy, jz = NN[i, 0], NN[i, 1], NN[i, 2], NN[j, 0], NN[j, 1], NN[j, 2]
            for q in range(n):
                c = ix[q] * jx[q] + iy[q] * jy[q] + iz[q] * jz[q]
                den = 1.0 - c * c
                ok = den > 1e-12
                den = den if ok else 1.0
                al = (a1[q] - c * a2[q]) / den
                be = (a2[q] - c * a1[q]) / den
                inside = ok and al >= 0.0 and be >= 0.0 and al + be > 0.0
                p0 = al * ix[q] + be * jx[q]
                p1 = al * iy[q] + be * jy[q]
                p2 = al * iz[q] + be * jz[q]
                pn = math.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
                cin = (p0 * tx[q] + p1 * ty[q] + p2 * tz[q]) / pn
                use1 = a1[q] >= a2[q]
                cos = cin if inside else (a1[q] if use1 else a2[q])
                c1[q] = al if inside else (1.0 if use1 else 0.0)
                c2[q] = be if inside else (0.0 if use1 else 1.0)
                better = cos > bc[q]
                upd[q] = 1.0 if better else 0.0
                bc[q] = cos if better else bc[q]
            for r in range(R):
                cr = C[r]
                src = c1 if r == i else c2
                if r == i or r == j:
                    for q in range(n):
                        cr[q] = src[q] if upd[q] != 0.0 else cr[q]
                else:
                    for q in range(n):
                        cr[q] = 0.0 if upd[q] != 0.0 else cr[q]
        # the truth inside the cone of three normals: t = x0 n_a + x1 n_b + x2 n_c, a
        # general 3x3 system (columns: unit normals), not the symmetric normal-matrix
        # solve of psbench.solve._sym3. Its guard only avoids dividing by 0: a thin cone
        # is a valid candidate (the relative rule of _sym3 on the Gram matrix would refuse
        # cones a few degrees wide and move the oracle at ~1 % of the pixels)
        for m in range(tris.shape[0]):
            a, b, c = tris[m, 0], tris[m, 1], tris[m, 2]
            for q in range(n):
                m00, m10, m20 = NN[a, 0, q], NN[a, 1, q], NN[a, 2, q]
                m01, m11, m21 = NN[b, 0, q], NN[b, 1, q], NN[b, 2, q]
                m02, m12, m22 = NN[c, 0, q], NN[c, 1, q], NN[c, 2, q]
                k00 = m11 * m22 - m12 * m21
                k01 = m02 * m21 - m01 * m22
                k02 = m01 * m12 - m02 * m11
                k10 = m12 * m20 - m10 * m22
                k11 = m00 * m22 - m02 * m20
                k12 = m02 * m10 - m00 * m12
                k20 = m10 * m21 - m11 * m20
                k21 = m01 * m20 - m00 * m21
                k22 = m00 * m11 - m01 * m10
                det = m00 * k00 + m10 * k01 + m20 * k02
                ok = abs(det) > 1e-9
                det = det if ok else 1.0
                x0 = (k00 * tx[q] + k01 * ty[q] + k02 * tz[q]) / det
                x1 = (k10 * tx[q] + k11 * ty[q] + k12 * tz[q]) / det
                x2 = (k20 * tx[q] + k21 * ty[q] + k22 * tz[q]) / det
                inside = ok and bc[q] < 1.0 and x0 >= 0.0 and x1 >= 0.0 and x2 >= 0.0
                c1[q] = x0
                c2[q] = x1
                c3[q] = x2
                upd[q] = 1.0 if inside else 0.0
                bc[q] = 1.0 if inside else bc[q]
            for r in range(R):
                cr = C[r]
                if r == a or r == b or r == c:
                    src = c1 if r == a else (c2 if r == b else c3)
                    for q in range(n):
                        cr[q] = src[q] if upd[q] != 0.0 else cr[q]
                else:
                    for q in range(n):
                        cr[q] = 0.0 if upd[q] != 0.0 else cr[q]
    # direction coefficients -> weights of the b_j: sum_j w_j rho_j n_j ∝ sum_j c_j n_j
    s = bc
    s[:n] = 0.0
    for j in range(R):
        cj, inv = C[j], INV[j]
        for q in range(n):
            cj[q] = cj[q] * inv[q]
            s[q] += cj[q]
    for j in range(R):
        cj = C[j]
        for q in range(n):
            cj[q] = np.float32(cj[q] / s[q]) if s[q] > 0.0 else np.float32(1.0 / R)


@njit(cache=True, nogil=True, error_model="numpy")
def _norms(B, n, RHO, INV):
    """rho_j = |b_j| and 1 / max(rho_j, 1e-30) for the block (weights, oracle, outputs)."""
    for j in range(B.shape[0]):
        bx, by, bz, rho, inv = B[j, 0], B[j, 1], B[j, 2], RHO[j], INV[j]
        for q in range(n):
            rho[q] = math.sqrt(bx[q] * bx[q] + by[q] * by[q] + bz[q] * bz[q])
            inv[q] = 1.0 / max(rho[q], 1e-30)


@njit(cache=True, nogil=True, error_model="numpy")
def _weigh_block(B, E2, RHO, INV, U, s, lo, n, kind, share, src, surf, sinz, rank, inv_zscale,
                 binary, T, pairs, tris):
    """The block's ring weights (R, n) into U (s: scratch)."""
    if kind == KIND_NONE:
        for j in range(B.shape[0]):
            U[j, :n] = share[j]
    elif kind == KIND_ORACLE:
        _oracle(B, RHO, INV, T, lo, U, n, pairs, tris, binary)
    else:
        _e_weights(B, E2, INV, U, s, n, src, surf, sinz, rank, inv_zscale, binary)


@njit(cache=True, nogil=True, error_model="numpy")
def _fuse_block(B, U, n, kind, F, Fb):
    """Eq. 4.9: Fb = sum_j w_j b_j; weight "None": least squares over every light,
    b = sum_j F_j b_j."""
    Fb[:, :n] = 0.0
    fx, fy, fz = Fb[0], Fb[1], Fb[2]
    for j in range(B.shape[0]):
        bx, by, bz = B[j, 0], B[j, 1], B[j, 2]
        if kind == KIND_NONE:
            f = F[j]
            f00, f01, f02, f10, f11 = f[0, 0], f[0, 1], f[0, 2], f[1, 0], f[1, 1]
            f12, f20, f21, f22 = f[1, 2], f[2, 0], f[2, 1], f[2, 2]
            for q in range(n):
                fx[q] += f00 * bx[q] + f01 * by[q] + f02 * bz[q]
                fy[q] += f10 * bx[q] + f11 * by[q] + f12 * bz[q]
                fz[q] += f20 * bx[q] + f21 * by[q] + f22 * bz[q]
        else:
            u = U[j]
            for q in range(n):
                fx[q] += u[q] * bx[q]
                fy[q] += u[q] * by[q]
                fz[q] += u[q] * bz[q]


@njit(cache=True, nogil=True, error_model="numpy")
def _residual_block(B, E2, Fb, n, G, count, lo, resid):
    """|I - S b| over every light by Pythagoras per ring:
    |I_j - S_j b|^2 = n_j e_j^2 + (b_j - b)^T G_j (b_j - b)."""
    fx, fy, fz = Fb[0], Fb[1], Fb[2]
    out = resid[lo:lo + n]
    for j in range(B.shape[0]):
        bx, by, bz, e2 = B[j, 0], B[j, 1], B[j, 2], E2[j]
        g = G[j]
        g00, g01, g02, g11, g12, g22 = g[0, 0], g[0, 1], g[0, 2], g[1, 1], g[1, 2], g[2, 2]
        c = np.float64(count[j])
        for q in range(n):
            d0, d1, d2 = bx[q] - fx[q], by[q] - fy[q], bz[q] - fz[q]
            r2 = (d0 * (g00 * d0 + 2.0 * (g01 * d1 + g02 * d2))
                  + d1 * (g11 * d1 + 2.0 * g12 * d2) + g22 * d2 * d2 + c * e2[q])
            if j == 0:
                out[q] = r2
            else:
                out[q] += r2
    for q in range(n):
        out[q] = math.sqrt(out[q])


@njit(cache=True, nogil=True, error_model="numpy")
def _store_fused(U, Fb, lo, n, with_b, b, w):
    """The block's fused outputs: b (N, 3) (written through a flat view: 2-d indexing
    of a slice would not vectorise) and the weights w (R, N)."""
    if with_b:
        fx, fy, fz = Fb[0], Fb[1], Fb[2]
        bo = b.reshape(-1)[3 * lo:3 * (lo + n)]
        for q in range(n):
            bo[3 * q] = fx[q]
            bo[3 * q + 1] = fy[q]
            bo[3 * q + 2] = fz[q]
    for j in range(U.shape[0]):
        u, wo = U[j], w[j, lo:lo + n]
        for q in range(n):
            wo[q] = u[q]


@njit(cache=True, nogil=True, error_model="numpy")
def _store_rings(B, E2, RHO, INV, lo, n, ring_normals, ring_albedo, ring_e):
    """The block's ring outputs: normals (0, 0, 1 where rho_j <= 1e-6), albedo and RMS
    residual of every ring."""
    for j in range(B.shape[0]):
        bx, by, bz, e2, rho, inv = B[j, 0], B[j, 1], B[j, 2], E2[j], RHO[j], INV[j]
        alb, e = ring_albedo[j, lo:lo + n], ring_e[j, lo:lo + n]
        nrm = ring_normals[j].reshape(-1)[3 * lo:3 * (lo + n)]
        for q in range(n):
            alb[q] = rho[q]
            e[q] = math.sqrt(e2[q])
            zero = rho[q] <= 1e-6
            f = 0.0 if zero else inv[q]
            nrm[3 * q] = bx[q] * f
            nrm[3 * q + 1] = by[q] * f
            nrm[3 * q + 2] = 1.0 if zero else bz[q] * f


def plain_rings(I2, order, start, P, F, G, count, kind, share, src, surf, sinz, rank,
                inv_zscale, binary, T, pairs, tris, b, resid, w, ring_normals=None,
                ring_albedo=None, ring_e=None):
    """Every ring's least squares, residual and weight, and the fusion, in one pass over
    the images (no mask).

    Parameters
    ----------
    I2 : (k, N) float32, C-contiguous
    order, start : (k,) and (R + 1,) int64
        Ring j's lights are ``order[start[j]:start[j + 1]]``.
    P : (k, 3) float64
        Row i of the pseudo-inverse of light i's ring: b_j = sum_{i in j} P_i I_i.
    F : (R, 3, 3) float64
        Least squares over every light from the ring solutions (weight "None").
    G : (R, 3, 3) float64
        S_j^T S_j.
    count : (R,) int64
        Lights per ring.
    kind, share, src, surf, sinz, rank, inv_zscale, binary, T, pairs, tris
        The weight (``wps._ring_setup``): kind, n_j / k (R,), sin Z_source factor?,
        surface factor?, sin Z_source_j (R,), zenith rank_j (R,), 1 / z_scale,
        one-hot?, truth normals (N, 3) float32 (oracle), ring pairs (P, 2) and
        triples (Q, 3) (oracle).
    b, resid, w, ring_normals, ring_albedo, ring_e : float32 outputs
        (N, 3) fused rho n, (N,) its residual norm over every image, (R, N) weights,
        (R, N, 3), (R, N), (R, N) RMS residual e_j. The ring outputs are optional
        (None: not written; :func:`ring_solutions` gives them from the same arithmetic).
    """
    R = count.shape[0]
    what = _ALL
    if ring_normals is None:
        what = _FUSED
        ring_normals, ring_albedo, ring_e = _no_rings(R)
    _pass(True, what, I2, order, start, P, F, G, count, np.empty((R, 3, 0), np.float32),
          np.empty((R, 0), np.float32), kind, share, src, surf, sinz, rank, inv_zscale, binary,
          T, pairs, tris, b, resid, w, ring_normals, ring_albedo, ring_e)


def ring_solutions(I2, order, start, P, G, count, ring_normals, ring_albedo, ring_e):
    """Every ring's normals, albedo and RMS residual alone, bit-identical to the ring
    outputs of :func:`plain_rings` (the same compiled solve; arguments as there)."""
    R = count.shape[0]
    z = np.zeros(R)
    t0 = np.zeros((1, 3), np.float32)
    i0 = np.zeros((0, 2), np.int64)
    _pass(True, _RINGS, I2, order, start, P, np.zeros((R, 3, 3)), G, count,
          np.empty((R, 3, 0), np.float32), np.empty((R, 0), np.float32), KIND_NONE, z, False,
          False, z, z, 1.0, False, t0, i0, np.zeros((0, 3), np.int64),
          np.empty((0, 3), np.float32), np.empty(0, np.float32), np.empty((R, 0), np.float32),
          ring_normals, ring_albedo, ring_e)


def _no_rings(R):
    return (np.empty((R, 0, 3), np.float32), np.empty((R, 0), np.float32),
            np.empty((R, 0), np.float32))


def weigh_rings(ring_b, e2, kind, share, src, surf, sinz, rank, inv_zscale, binary, T, pairs,
                tris, b, w, ring_normals, ring_albedo, ring_e):
    """Weights and fusion from given ring solutions (the masked path).

    ``ring_b`` (R, 3, N) float32 rho_j n_j and ``e2`` (R, N) float32 mean squared
    residuals of each ring's solve; the other arguments as :func:`plain_rings` (``b``
    is not written for weight "None", whose b is a solve over every image).
    """
    R = ring_b.shape[0]
    i0 = np.empty(0, np.int64)
    f0 = np.zeros((R, 3, 3))
    _pass(False, _ALL, np.empty((0, 0), np.float32), i0, i0, np.empty((0, 3)), f0, f0, i0,
          np.ascontiguousarray(ring_b, np.float32), np.ascontiguousarray(e2, np.float32), kind,
          share, src, surf, sinz, rank, inv_zscale, binary, T, pairs, tris, b,
          np.empty(0, np.float32), w, ring_normals, ring_albedo, ring_e)


@njit(cache=True, parallel=True, nogil=True, error_model="numpy")
def _pass(plain, what, I2, order, start, P, F, G, count, ring_b, e2, kind, share, src, surf,
          sinz, rank, inv_zscale, binary, T, pairs, tris, b, resid, w, ring_normals,
          ring_albedo, ring_e):
    """The one compiled kernel (one compilation for every path): ring solutions from the
    images (``plain``) or from ``ring_b`` / ``e2``, then weights, fusion and the fused
    outputs, the ring outputs, or both (``what``)."""
    R = F.shape[0]
    N = I2.shape[1] if plain else ring_b.shape[2]
    nblocks = (N + BLOCK - 1) // BLOCK
    for task in prange((nblocks + TASK - 1) // TASK):
        B = np.empty((R, 3, BLOCK))
        E2 = np.empty((R, BLOCK))
        U = np.empty((R, BLOCK))
        Fb = np.empty((3, BLOCK))
        s = np.empty((2, BLOCK))
        RHO = np.empty((R, BLOCK))
        INV = np.empty((R, BLOCK))
        for blk in range(task * TASK, min(nblocks, (task + 1) * TASK)):
            lo = blk * BLOCK
            n = min(BLOCK, N - lo)
            if plain:
                _solve_block(I2, lo, n, order, start, P, G, B, E2)
            else:
                for j in range(R):
                    for c in range(3):
                        B[j, c, :n] = ring_b[j, c, lo:lo + n]
                    E2[j, :n] = e2[j, lo:lo + n]
            _norms(B, n, RHO, INV)
            if what != _RINGS:
                _weigh_block(B, E2, RHO, INV, U, s, lo, n, kind, share, src, surf, sinz, rank,
                             inv_zscale, binary, T, pairs, tris)
                with_b = plain or kind != KIND_NONE
                if with_b:
                    _fuse_block(B, U, n, kind, F, Fb)
                if plain:
                    _residual_block(B, E2, Fb, n, G, count, lo, resid)
                _store_fused(U, Fb, lo, n, with_b, b, w)
            if what != _FUSED:
                _store_rings(B, E2, RHO, INV, lo, n, ring_normals, ring_albedo, ring_e)
