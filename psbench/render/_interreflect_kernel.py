"""Compiled inner loop of :mod:`psbench.render._interreflect` (numba, optional).

One call handles one chunk of the sheared working grid of one azimuth and every
elevation of it: per working column (a ray track; columns run in parallel) and per
elevation, a single far-to-near sweep keeps the "staircase" of the track beyond the
current origin -- the positions whose lifted height ``g = h - T rho - bias`` exceeds
that of every position nearer the origin, so their g increase with the distance --
and the first hit of the ray from rho is the nearest staircase entry with g above the
origin's (a binary search in the stack). That is O(L log L) per track instead of the
O(L log L) *vectorised passes* of the numpy fallback, and the light loop is fused
in. Same definitions and results as the numpy path (tests compare the two), except
that the specular lobes are read from a 4097-entry table with linear interpolation
(error < 1e-5).

Importing this module raises ImportError when numba is missing; the caller falls
back to numpy.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["chunk", "backmap", "lobe_table", "TABLE"]

#: entries of the lobe tables over c in [-1, 1]
TABLE = 4097
_NOTHING = np.float32(-3e38)


def lobe_table(model, m, phong_m):
    """The specular lobe tabulated over c = -1 .. 1 (TS: c = n.h; Phong: c = r.v)."""
    c = np.linspace(-1.0, 1.0, TABLE)
    if model == "ts":
        return np.exp(-(m * np.arccos(c)) ** 2).astype(np.float32)
    return (np.maximum(c, 0.0) ** phong_m).astype(np.float32)


@njit(inline="always", fastmath=True)
def _lookup(tab, c):
    x = (c + 1.0) * 0.5 * (tab.shape[0] - 1)
    if x <= 0.0:
        return tab[0]
    if x >= tab.shape[0] - 1:
        return tab[tab.shape[0] - 1]
    i = int(x)
    f = x - i
    return tab[i] + f * (tab[i + 1] - tab[i])


@njit(parallel=True, fastmath=True, cache=True)
def chunk(occ, org, nrm, recv, f0, f1, ft, E, lit, hv, sdirs, emit_model, etab, recv_model,
          rtab, T, wd, wq, bias, Ac, As):  # pragma: no cover - compiled
    """Accumulate the secondary light of one working-grid chunk.

    occ, org : (L, nc) float32 occluder heights (``_NOTHING`` off the image) and
        origin heights; nrm (L, nc, 3); recv (L, nc) bool receivers;
    f0, f1, ft : (L, nc) the two source rows of every working sample and the weight
        of the second (the across-ray linear resampling);
    E : (N, k) diffuse emission of the padded image; lit : (N, k) lit x rho_s x power
        (specular emission; unused when emit_model == 0);
    hv : (n_el, k, 3) TS half vectors normalise(s_i - w); sdirs (k, 3);
    emit_model, recv_model : 0 none, 1 ts, 2 phong; etab, rtab: lobe tables;
    T : (n_el,) rise per step; wd : (n_el, 3) directions; wq : quadrature weight;
    Ac, As : (L, nc, k) float32 accumulators (cos-weighted / receiver-lobe-weighted).
    """
    L, nc = occ.shape
    k = E.shape[1]
    n_el = T.shape[0]
    lo = np.float32(-1e37)
    for c in prange(nc):
        st = np.empty(L, np.int64)
        sv = np.empty(L, np.float32)
        for e in range(n_el):
            t = T[e]
            wx, wy, wz = wd[e, 0], wd[e, 1], wd[e, 2]
            top = 0
            for r in range(L - 1, -1, -1):
                if recv[r, c] and top > 0:
                    cosr = nrm[r, c, 0] * wx + nrm[r, c, 1] * wy + nrm[r, c, 2] * wz
                    thr = org[r, c] - t * r
                    if cosr > 0.0 and sv[0] > thr:
                        a, b = 0, top - 1  # largest p with sv[p] > thr (sv decreasing in p)
                        while a < b:
                            mid = (a + b + 1) // 2
                            if sv[mid] > thr:
                                a = mid
                            else:
                                b = mid - 1
                        x = st[a]
                        v1 = sv[a]
                        v0 = occ[x - 1, c] - t * (x - 1) - bias
                        u = 1.0
                        if occ[x - 1, c] > lo and v1 > v0:
                            u = (thr - v0) / (v1 - v0)
                            u = min(max(u, 0.0), 1.0)
                        nx = nrm[x - 1, c, 0] + u * (nrm[x, c, 0] - nrm[x - 1, c, 0])
                        ny = nrm[x - 1, c, 1] + u * (nrm[x, c, 1] - nrm[x - 1, c, 1])
                        nz = nrm[x - 1, c, 2] + u * (nrm[x, c, 2] - nrm[x - 1, c, 2])
                        if nx * wx + ny * wy + nz * wz < 0.0:  # the hit faces the receiver
                            wc = wq * cosr
                            ws = 0.0
                            if recv_model == 1:
                                hx, hy, hz = wx, wy, wz + 1.0
                                hn = np.sqrt(hx * hx + hy * hy + hz * hz)
                                ws = wq * _lookup(rtab, (nrm[r, c, 0] * hx + nrm[r, c, 1] * hy
                                                         + nrm[r, c, 2] * hz) / hn)
                            elif recv_model == 2:
                                ws = wq * _lookup(rtab, 2.0 * cosr * nrm[r, c, 2] - wz)
                            nn = np.sqrt(nx * nx + ny * ny + nz * nz)
                            nw = nx * wx + ny * wy + nz * wz
                            # the hit's four source pixels and their weights
                            a0, a1, b0, b1 = f0[x - 1, c], f1[x - 1, c], f0[x, c], f1[x, c]
                            ta, tb = ft[x - 1, c], ft[x, c]
                            wa0, wa1 = (1.0 - u) * (1.0 - ta), (1.0 - u) * ta
                            wb0, wb1 = u * (1.0 - tb), u * tb
                            for i in range(k):
                                R = wa0 * E[a0, i] + wa1 * E[a1, i] + wb0 * E[b0, i] + wb1 * E[b1, i]
                                if emit_model != 0:
                                    li = (wa0 * lit[a0, i] + wa1 * lit[a1, i] + wb0 * lit[b0, i]
                                          + wb1 * lit[b1, i])
                                    if li > 0.0:
                                        if emit_model == 1:
                                            cc = (nx * hv[e, i, 0] + ny * hv[e, i, 1]
                                                  + nz * hv[e, i, 2]) / nn
                                        else:
                                            sn = nx * sdirs[i, 0] + ny * sdirs[i, 1] + nz * sdirs[i, 2]
                                            sw = sdirs[i, 0] * wx + sdirs[i, 1] * wy + sdirs[i, 2] * wz
                                            cc = -2.0 * sn * nw + sw
                                        R += li * _lookup(etab, cc)
                                Ac[r, c, i] += wc * R
                                if recv_model != 0:
                                    As[r, c, i] += ws * R
                # push r: drop the entries it hides (not higher than it), then push it
                g = occ[r, c] - t * r - bias
                while top > 0 and sv[top - 1] <= g:
                    top -= 1
                st[top] = r
                sv[top] = g
                top += 1


@njit(fastmath=True, cache=True)
def backmap(A, brho, bjf, bt, ja, jb, acc):  # pragma: no cover - compiled
    """acc[p] += A at the working position (brho[p], bjf[p] + bt[p]) of every pixel p
    whose left neighbour column lies in [ja, jb - 1); A (L, nc, k), acc (N, k)."""
    k = A.shape[2]
    for p in range(brho.shape[0]):
        j = bjf[p]
        if j < ja or j >= jb - 1:
            continue
        r = brho[p]
        t = bt[p]
        for i in range(k):
            acc[p, i] += (1.0 - t) * A[r, j - ja, i] + t * A[r, j - ja + 1, i]
