"""Brute-force reference for :mod:`psbench.render._interreflect` (small scenes only).

An independent discretisation of the same one-bounce integral, written as a sum
over surface *patches* instead of directions:

    I_sec(p) = sum_q R_q(-w) / pi [rho_d (w.n_p) + rho_s S(n_p, w, v)] (-w.n_q) / r^2 dA_q V(p, q)

with w = (q - p) / r, q running over ``sub x sub`` sub-samples of every object pixel
(heights bilinear, normal and emission of the pixel, dA = 1 / (sub^2 n_z)), both
cosines positive, and V the visibility: the segment p-q must not pass below the
bilinear height field by more than ``bias`` (checked every half pixel; ``visibility=
False`` skips the test, exact for surfaces whose points all see each other such as
``cup`` and ``vgroove``). O(N^2) memory-chunked numpy: a few thousand pixels.
"""
from __future__ import annotations

import numpy as np

from ._shading import lobe as _lobe

__all__ = ["reference"]


def _bilinear(h, x, y):
    """Heights at frame coordinates (x right, y up) of the (H, W) map, edge-clamped."""
    H, W = h.shape
    c = np.clip(x + (W - 1) / 2.0, 0, W - 1)
    r = np.clip((H - 1) / 2.0 - y, 0, H - 1)
    c0 = np.minimum(np.floor(c).astype(np.int64), W - 2)
    r0 = np.minimum(np.floor(r).astype(np.int64), H - 2)
    fc, fr = c - c0, r - r0
    return ((1 - fr) * ((1 - fc) * h[r0, c0] + fc * h[r0, c0 + 1])
            + fr * ((1 - fc) * h[r0 + 1, c0] + fc * h[r0 + 1, c0 + 1]))


def reference(height, normals, emitted, *, object_mask=None, rho_d=1.0, specular=None,
              sub=3, visibility=True, bias=1e-3, chunk=64):
    """One-bounce secondary light by a brute-force patch sum, (k, H, W) float64.

    Parameters as :func:`psbench.render._interreflect.secondary` (``specular`` holds the
    same :class:`~psbench.render._interreflect.Specular`); ``sub``: emitter sub-samples per
    pixel side; ``visibility``: test occlusion (see the module docstring).
    """
    h = np.asarray(height, np.float64)
    H, W = h.shape
    n = np.asarray(normals, np.float64).reshape(H, W, 3)
    E = np.asarray(emitted, np.float64)
    k = E.shape[0]
    object_mask = np.ones((H, W), bool) if object_mask is None else np.asarray(object_mask, bool)
    xs = np.arange(W) - (W - 1) / 2.0
    ys = (H - 1) / 2.0 - np.arange(H)
    rr, cc = np.nonzero(object_mask)
    # emitter sub-samples
    o = (np.arange(sub) + 0.5) / sub - 0.5
    ex = (xs[cc][:, None, None] + o[None, None, :]).repeat(sub, 1).reshape(-1)
    ey = (ys[rr][:, None, None] - o[None, :, None]).repeat(sub, 2).reshape(-1)
    idx = np.repeat(np.arange(rr.size), sub * sub)
    ez = _bilinear(h, ex, ey)
    en = n[rr, cc][idx]
    dA = 1.0 / (sub * sub * np.maximum(en[:, 2], 1e-6))
    eE = E[:, rr, cc][:, idx].T  # (M, k)
    spec = specular
    if spec is not None:
        lit = np.asarray(spec.lit)[:, rr, cc][:, idx].T.astype(np.float64)
        rs = spec.rho_s
        rs_e = float(rs) if np.ndim(rs) == 0 else np.asarray(rs, np.float64)[rr, cc][idx]
        rs_p = rs if np.ndim(rs) == 0 else np.asarray(rs, np.float64)[rr, cc]
        S = np.asarray(spec.directions, np.float64)
        mu = np.asarray(spec.power, np.float64)
    rd_p = rho_d if np.ndim(rho_d) == 0 else np.asarray(rho_d, np.float64)[rr, cc]
    out = np.zeros((k, H, W))
    P = np.stack([xs[cc], ys[rr], h[rr, cc]], 1)
    Pn = n[rr, cc]
    Q = np.stack([ex, ey, ez], 1)
    for a in range(0, P.shape[0], chunk):
        p, pn = P[a:a + chunk], Pn[a:a + chunk]
        d = Q[None] - p[:, None]  # (c, M, 3)
        r2 = np.einsum("cmx,cmx->cm", d, d)
        r = np.sqrt(np.maximum(r2, 1e-12))
        w = d / r[..., None]
        cp = np.einsum("cmx,cx->cm", w, pn)
        cq = -np.einsum("cmx,mx->cm", w, en)
        with np.errstate(invalid="ignore", divide="ignore"):
            g = np.where((cp > 0) & (cq > 0) & (r2 > 1e-9), cq * dA[None] / (np.pi * r2), 0.0)
        if visibility:
            g *= _visible(h, p, Q, d, r, bias)
        fd = (rd_p if np.ndim(rd_p) == 0 else rd_p[a:a + chunk, None]) * np.maximum(cp, 0)
        if spec is None:
            out[:, rr[a:a + chunk], cc[a:a + chunk]] = ((g * fd) @ eE).T
            continue
        # receiver's specular response to light from w, seen from v = +z
        if spec.model == "ts":
            hv = w + np.array([0, 0, 1.0])
            hv /= np.linalg.norm(hv, axis=-1, keepdims=True)
            cr = np.einsum("cmx,cx->cm", hv, pn)
        else:
            cr = 2 * cp * pn[:, None, 2] - w[..., 2]
        fs = _lobe(spec.model, cr.astype(np.float32), spec.m, spec.phong_m).astype(np.float64)
        fs *= (rs_p if np.ndim(rs_p) == 0 else rs_p[a:a + chunk, None])
        for i in range(k):  # emitter's specular lobe towards -w
            if spec.model == "ts":
                hv = S[i][None, None] - w
                hv /= np.maximum(np.linalg.norm(hv, axis=-1, keepdims=True), 1e-12)
                ce = np.einsum("cmx,mx->cm", hv, en)
            else:
                sn = en @ S[i]
                ce = -2 * sn[None] * np.einsum("cmx,mx->cm", w, en) + w @ S[i]
            em = _lobe(spec.model, ce.astype(np.float32), spec.m, spec.phong_m).astype(np.float64)
            em *= mu[i] * lit[:, i][None] * (rs_e if np.ndim(rs_e) == 0 else rs_e[None])
            R = eE[:, i][None] + em
            out[i, rr[a:a + chunk], cc[a:a + chunk]] = (g * R * (fd + fs)).sum(1)
    return out


def _visible(h, p, Q, d, r, bias):
    """(c, M) 1.0 where the segment from p to Q stays above the bilinear heights."""
    hor = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
    steps = int(np.ceil(hor.max() * 2)) + 1
    vis = np.ones(hor.shape, bool)
    for s in np.linspace(0, 1, steps + 1)[1:-1]:
        x = p[:, None, 0] + s * d[..., 0]
        y = p[:, None, 1] + s * d[..., 1]
        z = p[:, None, 2] + s * d[..., 2]
        near = (s * hor < 0.75) | ((1 - s) * hor < 0.75)  # the patches themselves
        vis &= near | (_bilinear(h, x, y) <= z + bias)
    return vis.astype(np.float64)
