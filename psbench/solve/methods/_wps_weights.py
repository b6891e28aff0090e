"""The ring weights of WPS (Eqs. 4.9-4.16): sigmoid, surface factor, oracle, fusion.

See :mod:`psbench.solve.methods.wps` for the decisions behind them.
"""
from __future__ import annotations

import itertools

import numpy as np

__all__ = ["WEIGHTS", "DEFAULT_WEIGHT", "sig", "surface_factor", "oracle_weights", "fuse"]

#: weight definitions (Section 4.3) plus the oracle limit and plain PS
WEIGHTS = ("None", "e", "eZsource", "eZsurface", "eZsourceZsurface", "oracle")
DEFAULT_WEIGHT = "eZsourceZsurface"


def sig(x):
    """The sigmoid of Eq. 4.15, ``1 / (1 + exp(-10 (x - 0.5)))``."""
    x = np.asarray(x, dtype=np.float32)
    return (1.0 / (1.0 + np.exp(np.float32(-10.0) * (x - np.float32(0.5))))).astype(np.float32)


def surface_factor(zenith_deg, rank, *, z_scale=90.0):
    """Surface-zenith weight factor of a ring (module docs).

    Parameters
    ----------
    zenith_deg : array_like
        Surface zenith of the ring's estimated normal, degrees.
    rank : float
        Zenith rank of the ring in [0, 1]: 0 = lowest source zenith, 1 = highest.
    z_scale : float
        Degrees mapped to x = 1 (default 90).
    """
    z = np.asarray(zenith_deg, dtype=np.float32) / np.float32(z_scale)
    t = np.float32(rank)
    return sig((1 - t) * z + t * (1 - z))


def _arc_best(n1, n2, r):
    """Per-pixel best direction on the arc between unit n1 and n2 (3, N) w.r.t. r.

    Returns (c1, c2, cos): nonnegative coefficients of the direction c1 n1 + c2 n2
    (unnormalised) and its cosine with r.
    """
    a1 = (n1 * r).sum(0)
    a2 = (n2 * r).sum(0)
    c = (n1 * n2).sum(0)
    den = 1.0 - c * c
    ok = den > 1e-12
    den = np.where(ok, den, 1.0)
    al = (a1 - c * a2) / den
    be = (a2 - c * a1) / den
    inside = ok & (al >= 0) & (be >= 0) & ((al + be) > 0)
    p = al * n1 + be * n2
    pn = np.sqrt((p * p).sum(0))
    cos_in = np.where(inside, (p * r).sum(0) / np.where(inside, pn, 1.0), -2.0)
    # endpoints
    use1 = a1 >= a2
    c1 = np.where(inside, al, np.where(use1, 1.0, 0.0))
    c2 = np.where(inside, be, np.where(use1, 0.0, 1.0))
    cos = np.where(inside, cos_in, np.maximum(a1, a2))
    return c1, c2, cos


def oracle_weights(ring_b, truth, *, binary=False):
    """Oracle ring weights (module docs): best fusion direction per pixel.

    Parameters
    ----------
    ring_b : (R, 3, N) float
        Albedo-scaled ring normals.
    truth : (3, N) float
        True normals.
    binary : bool
        Pick the single ring closest to the truth.

    Returns
    -------
    w : (R, N) float32
        Nonnegative weights summing to 1 with ``sum_j w_j b_j`` along the best direction.
    """
    B = np.asarray(ring_b, dtype=np.float64)
    R, _, N = B.shape
    rho = np.sqrt((B * B).sum(1))  # (R, N)
    n = B / np.maximum(rho, 1e-30)[:, None]
    r = np.asarray(truth, dtype=np.float64)
    r = r / np.maximum(np.sqrt((r * r).sum(0)), 1e-30)
    # direction coefficients c (R, N) for n (not b): start with the best single ring
    cos_single = (n * r[None]).sum(1)  # (R, N)
    best = np.argmax(cos_single, axis=0)
    bestcos = np.take_along_axis(cos_single, best[None], 0)[0]
    C = np.zeros((R, N))
    C[best, np.arange(N)] = 1.0
    if not binary:
        for i, j in itertools.combinations(range(R), 2):
            c1, c2, cos = _arc_best(n[i], n[j], r)
            better = cos > bestcos
            if better.any():
                C[:, better] = 0.0
                C[i, better] = c1[better]
                C[j, better] = c2[better]
                bestcos = np.where(better, cos, bestcos)
        for tri in itertools.combinations(range(R), 3):
            M = np.stack([n[t] for t in tri], axis=-1)  # (3, N, 3): columns n_t
            Mt = np.moveaxis(M, 1, 0)  # (N, 3, 3)
            det = np.linalg.det(Mt)
            ok = np.abs(det) > 1e-9
            if not ok.any():
                continue
            coef = np.zeros((N, 3))
            coef[ok] = np.linalg.solve(Mt[ok], r.T[ok][..., None])[..., 0]
            inside = ok & (coef >= 0).all(axis=1) & (bestcos < 1.0)
            if inside.any():
                C[:, inside] = 0.0
                for q, t in enumerate(tri):
                    C[t, inside] = coef[inside, q]
                bestcos = np.where(inside, 1.0, bestcos)
    # direction coefficients -> b weights: sum_j w_j rho_j n_j ∝ sum_j c_j n_j
    w = C / np.maximum(rho, 1e-30)
    s = w.sum(0)
    w = np.where(s > 0, w / np.where(s > 0, s, 1.0), 1.0 / R)
    return w.astype(np.float32)


def fuse(ring_b, w):
    """Eq. 4.9: ``sum_j w_j b_j`` for ring_b (R, 3, N) and w (R, N) -> (3, N)."""
    out = ring_b[0] * w[0]
    for j in range(1, len(ring_b)):
        out += ring_b[j] * w[j]
    return out


def _dot3(a, b):
    """Row-wise dot product of two (3, N) arrays."""
    out = a[0] * b[0]
    out += a[1] * b[1]
    out += a[2] * b[2]
    return out


def _quad3(d, G):
    """d^T G d per column of a (3, N) array, symmetric 3x3 G."""
    G = np.asarray(G, dtype=np.float32)
    d0, d1, d2 = d
    out = (G[0, 0] * d0 + np.float32(2) * (G[0, 1] * d1 + G[0, 2] * d2)) * d0
    out += (G[1, 1] * d1 + np.float32(2) * G[1, 2] * d2) * d1
    out += G[2, 2] * d2 * d2
    return out


def _transpose(b, N):
    """(3, N) -> contiguous (N, 3)."""
    out = np.empty((N, 3), dtype=np.float32)
    for c in range(3):
        out[:, c] = b[c]
    return out
