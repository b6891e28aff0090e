"""Global start of tsfit: the best normal of a hemisphere lattice, for every pixel.

For a fixed candidate normal the model's columns (d f / d rho_d, d f / d rho_s) are the
same at every pixel, so the closed-form cost of every (pixel, candidate) pair follows
from five matrix products of per-light tables with the weights and observations.
"""
from __future__ import annotations

import numpy as np

from . import _lm

__all__ = ["hemisphere", "grid_start"]

#: (candidates or lights) x pixels per block: a few MB of working set
BLOCK_ELEMS = 1 << 16


def hemisphere(count):
    """``count`` nearly uniform unit vectors with z > 0 (Fibonacci lattice), (count, 3)."""
    i = np.arange(count) + 0.5
    z = 1.0 - i / count  # uniform in z on the upper hemisphere
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _explained(a00, a01, a11, r0, r1, rs):
    """-(energy explained) by the best nonnegative (rho_d, rho_s) of each candidate:
    the weighted cost minus sum w I^2. ``rs`` (p,) given: rho_d alone."""
    if rs is not None:  # rs^2 a11 - 2 rs r1 - max(r0 - rs a01, 0)^2 / a00
        t = np.maximum(r0 - rs * a01, 0.0)
        return rs * (rs * a11 - 2.0 * r1) - t * t / np.maximum(a00, 1e-30)
    with np.errstate(all="ignore"):
        det = a00 * a11 - a01 * a01
        ok = det > 1e-12 * (a00 * a11 + 1e-30)
        inv = 1.0 / np.where(ok, det, 1.0)
        x0 = (a11 * r0 - a01 * r1) * inv
        x1 = (a00 * r1 - a01 * r0) * inv
        both = ok & (x0 >= 0) & (x1 >= 0)
        e_d = np.where(r0 > 0, r0 * r0 / np.maximum(a00, 1e-30), 0.0)  # rho_s = 0
        e_s = np.where(r1 > 0, r1 * r1 / np.maximum(a11, 1e-30), 0.0)  # rho_d = 0
        return -np.where(both, x0 * r0 + x1 * r1, np.maximum(e_d, e_s))


def grid_start(L, I, w, n0, m_value, count=256, rs=None):
    """Best start normal per pixel among a hemisphere grid and ``n0``.

    For every candidate normal the costs of all pixels follow from five matrix
    products with per-light tables (rho_d, and rho_s unless ``rs`` (p,) is given,
    in closed form; the lobe width fixed at ``m_value``).

    Returns
    -------
    n : (3, p) float32
    cost : (p,) the best cost minus sum w I^2
    """
    C = hemisphere(count)
    c = C @ L.d.T.astype(np.float64)  # (J, k)
    th = np.arccos(np.clip(C @ L.h.T.astype(np.float64), -1, 1))
    lit = (c > 0) * L.mu.astype(np.float64)
    Pd = c * lit  # d f / d rho_d
    Ps = np.exp(-(m_value * th) ** 2) * lit
    quad = np.concatenate([Pd * Pd, Pd * Ps, Ps * Ps]).astype(np.float32)  # (3J, k)
    lin = np.concatenate([Pd, Ps]).astype(np.float32)  # (2J, k)
    k, P = I.shape
    J = count
    block = max(64, BLOCK_ELEMS // max(J, k))
    best = np.empty(P)
    arg = np.empty(P, dtype=np.int64)
    for lo in range(0, P, block):
        s = slice(lo, min(P, lo + block))
        wb = w[:, s]
        a = quad @ wb
        r = lin @ (wb * I[:, s])
        e = _explained(a[:J], a[J:2 * J], a[2 * J:], r[:J], r[J:],
                       None if rs is None else rs[s].astype(np.float32))
        arg[s] = np.argmin(e, axis=0)
        best[s] = e[arg[s], np.arange(e.shape[1])]
    # the given start competes with the grid
    m = np.full(P, m_value, dtype=np.float32)
    _, _, own = _lm.init_rho(L, I, w, n0, m, np.full(P, np.inf, dtype=np.float32), rs=rs,
                             cost=True)
    own -= np.einsum("kp,kp->p", w * I, I, dtype=np.float64)
    use = best < own
    n = np.where(use, C[arg].T.astype(np.float32), n0)
    return n, np.where(use, best, own)
