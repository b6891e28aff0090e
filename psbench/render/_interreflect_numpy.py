"""Vectorised numpy fallback of the interreflection gather (no numba).

Same quadrature as :mod:`psbench._interreflect_kernel`, organised per elevation over
all working-grid origins at once: the first hit of every ray is found by binary
lifting on a sparse table of running maxima (O(N log L) vectorised work per
direction) and the lights are gathered with fancy indexing. Exact lobes (no table).
"""
from __future__ import annotations

import math

import numpy as np

from ._shading import lobe as _lobe

__all__ = ["run"]

_NOTHING = np.float32(-3e38)


def run(geo, specular, spec_e, occ, org, nrm, rec, Ec, Lc, wd, T, Ac, As):
    """Accumulate one working-grid chunk into Ac / As ((L nc, k), flat), in place.

    ``geo`` is the :class:`psbench.render._interreflect._Geometry` (bias, weight, lobes);
    the other arguments are those of :func:`psbench._interreflect_kernel.chunk` with
    the emission already resampled onto the grid (``Ec`` (L, nc, k), ``Lc`` (L nc, k)).
    """
    L, nc, k = Ec.shape
    occ, org = occ.ravel(), org.ravel()
    nrm = nrm.reshape(-1, 3)
    Ec = Ec.reshape(-1, k)
    recv = np.flatnonzero(rec.ravel())
    nr = nrm[recv]
    rho = np.arange(L, dtype=np.float32)[:, None]
    levels = None
    for e in range(len(T)):
        w = wd[e]
        cos_r = nr @ w
        pos_r = cos_r > 0
        o = recv[pos_r]
        if o.size == 0:
            continue
        cos_o = cos_r[pos_r]
        g = occ.reshape(L, nc) - T[e] * rho
        g -= geo.bias
        levels = _levels(g, levels)
        ro, co = np.divmod(o, nc)
        thr = org[o] - T[e] * ro.astype(np.float32)
        pos = _first_above(levels, ro, co, thr, L, nc)
        hit = pos < L - 1
        if not hit.any():
            continue
        o, cos_o, thr = o[hit], cos_o[hit], thr[hit]
        q1 = (pos[hit] + 1) * nc + co[hit]
        q0 = q1 - nc
        gf = g.ravel()
        g0, g1 = gf[q0], gf[q1]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            u = np.where((occ[q0] > -1e37) & (g1 > g0), (thr - g0) / (g1 - g0), 1.0)
        u = np.clip(u, 0.0, 1.0).astype(np.float32)[:, None]
        nq_ = nrm[q0] * (1 - u) + nrm[q1] * u
        front = (nq_ @ w) < 0  # the hit point faces the receiver
        R = Ec[q0] * (1 - u) + Ec[q1] * u
        if spec_e is not None:
            R += _emit_spec(spec_e, nq_, w, Lc[q0] * (1 - u) + Lc[q1] * u)
        R *= front[:, None]
        Ac[o] += (np.float32(geo.w) * cos_o)[:, None] * R
        if As is not None:
            As[o] += (np.float32(geo.w) * _recv_spec(specular, nrm[o], w))[:, None] * R


def _emit_spec(spec, nq, w, lit):
    """Specular light sent by hit points (normals nq (n, 3)) towards -w, (n, k);
    ``lit`` is lit x rho_s x power."""
    S_dirs = np.asarray(spec.directions, np.float32)
    if spec.model == "ts":
        hv = S_dirs - w[None, :]
        hv /= np.maximum(np.linalg.norm(hv, axis=1, keepdims=True), 1e-12)
        nn = nq / np.maximum(np.linalg.norm(nq, axis=1, keepdims=True), 1e-12)
        c = nn @ hv.T
    else:  # r.(-w), r = 2 (s.n) n - s
        sn = nq @ S_dirs.T
        c = -2.0 * sn * (nq @ w)[:, None] + (S_dirs @ w)[None, :]
    lobe = _lobe(spec.model, np.ascontiguousarray(c, np.float32), spec.m, spec.phong_m)
    lobe *= lit
    return lobe


def _recv_spec(spec, n, w):
    """Receivers' specular response to light from w seen from v = +z, (n,)."""
    if spec.model == "ts":
        hv = w + np.float32([0, 0, 1])
        hv /= np.linalg.norm(hv)
        c = n @ hv
    else:
        c = 2.0 * (n @ w) * n[:, 2] - w[2]
    return _lobe(spec.model, np.ascontiguousarray(c, np.float32), spec.m, spec.phong_m)


def _levels(g, out=None):
    """Sparse table: levels[j][rho] = max(g[rho + 1 .. rho + 2^j]) (-inf past the end)."""
    L, nc = g.shape
    J = max(1, int(math.ceil(math.log2(max(L, 2)))))
    if out is None or out.shape != (J, L, nc):
        out = np.empty((J, L, nc), np.float32)
    out[0, :-1] = g[1:]
    out[0, -1] = _NOTHING
    for j in range(1, J):
        s = 1 << (j - 1)
        np.copyto(out[j], out[j - 1])
        if s < L:
            np.maximum(out[j, :-s], out[j - 1, s:], out=out[j, :-s])
    return out


def _first_above(levels, ro, co, thr, L, nc):
    """Binary lifting: the last position pos >= ro with g[ro + 1 .. pos] <= thr; the
    first hit is pos + 1 (none when pos >= L - 1)."""
    pos = ro.astype(np.int64)
    flat = levels.reshape(levels.shape[0], -1)
    for j in range(levels.shape[0] - 1, -1, -1):
        idx = np.minimum(pos, L - 1) * nc + co
        adv = (flat[j][idx] <= thr) | (pos >= L - 1)
        pos += adv.astype(np.int64) << j
    return pos
