"""The ring weights of WPS (Eqs. 4.9-4.16): sigmoid, surface factor, oracle, fusion.

See :mod:`psbench.solve.methods.wps` for the decisions behind them. ``wps`` itself
computes them per pixel in :mod:`psbench.solve.methods.wps._kernel`; ``sig`` and
``surface_factor`` are the same formulas on arrays, ``oracle_weights`` calls the kernel.
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


def oracle_weights(ring_b, truth, *, binary=False):
    """Oracle ring weights (module docs of :mod:`psbench.solve.methods.wps`): the
    fusion direction closest to the truth per pixel.

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
    from . import _kernel as _k

    B = np.ascontiguousarray(ring_b, dtype=np.float32)
    R, _, N = B.shape
    T = np.require(np.asarray(truth, dtype=np.float32).T, np.float32, ["C", "W"])
    pairs = np.array(list(itertools.combinations(range(R), 2)), dtype=np.int64).reshape(-1, 2)
    tris = np.array(list(itertools.combinations(range(R), 3)), dtype=np.int64).reshape(-1, 3)
    zeros = np.zeros(R)
    w = np.empty((R, N), dtype=np.float32)
    _k.weigh_rings(B, np.zeros((R, N), dtype=np.float32), _k.KIND_ORACLE, zeros, False, False,
                   zeros, zeros, 1.0, bool(binary), T, pairs, tris,
                   np.empty((N, 3), dtype=np.float32), w, np.empty((R, N, 3), dtype=np.float32),
                   np.empty((R, N), dtype=np.float32), np.empty((R, N), dtype=np.float32))
    return w


def fuse(ring_b, w):
    """Eq. 4.9: ``sum_j w_j b_j`` for ring_b (R, 3, N) and w (R, N) -> (3, N)."""
    out = ring_b[0] * w[0]
    for j in range(1, len(ring_b)):
        out += ring_b[j] * w[j]
    return out
