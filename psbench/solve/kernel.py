"""The one weighted least-squares kernel behind every psbench solve.

Per pixel p, with weights w_i(p) >= 0 (binary masks are 0/1 weights), solve

    (sum_i w_i s_i s_i^T) b = sum_i w_i I_i s_i,      b = rho * n,

by forming the six unique entries of the 3x3 normal matrix with one matrix product
over all pixels and inverting it in closed form (adjugate / determinant). No Python
loop runs over pixels; the pixel axis is processed in chunks to bound memory.
"""
from __future__ import annotations

import numpy as np

from ._sym3 import sym3_cofactors, sym3_solve

__all__ = ["wls", "ls", "split", "lambert", "residuals", "residual_norm", "ls_residual_norm",
           "complete_three", "sym3_cofactors", "CHUNK"]

#: pixels per chunk (bounds temporaries at ~k * CHUNK * 4 bytes)
CHUNK = 1 << 18

_IU = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))


def ls(images, S):
    """Unweighted least squares b = S^+ I (Eq. 2.17-2.18).

    Parameters
    ----------
    images : (k, H, W) float32
    S : (k, 3) array_like
        Illumination vectors s_i = mu_i d_i.

    Returns
    -------
    b : (H, W, 3) float32
        Albedo-scaled normals rho * n.
    """
    k, H, W = images.shape
    P = np.linalg.pinv(np.asarray(S, dtype=np.float64)).astype(np.float32)  # (3, k)
    # (N, k) @ (k, 3) on a transposed view writes the (H, W, 3) layout directly
    return (images.reshape(k, -1).T @ P.T).reshape(H, W, 3)


def wls(images, S, weights=None):
    """Weighted least squares per pixel, closed-form 3x3 normal equations.

    Parameters
    ----------
    images : (k, H, W) float32
    S : (k, 3) array_like
    weights : (k, H, W) float32 or bool, optional
        Per-observation weights (True/1 = used). None: plain least squares.

    Returns
    -------
    b : (H, W, 3) float32
        rho * n. Pixels whose weighted normal matrix is singular (fewer than three
        independent observations with weight) fall back to plain least squares;
        callers that mask use :func:`complete_three` first so this never happens
        for 0/1 masks.
    """
    if weights is None:
        return ls(images, S)
    k, H, W = images.shape
    S = np.asarray(S, dtype=np.float64)
    # the normal matrix holds products of two light vectors in float32: scale S by a
    # power of two (exact) so that very bright or dim lights (power 1e30 or 1e-30)
    # neither overflow nor underflow; b scales back by the same factor
    c = _pow2(np.sqrt(np.max(np.einsum("ij,ij->i", S, S))))
    if c != 1.0:
        S = S * c
    outer = (S[:, :, None] * S[:, None, :])[:, _IU[0], _IU[1]].astype(np.float32)  # (k, 6)
    St = S.T.astype(np.float32)  # (3, k)
    I2 = images.reshape(k, -1)
    W2 = weights.reshape(k, -1)
    N = I2.shape[1]
    out = np.empty((N, 3), dtype=np.float32)
    P = np.linalg.pinv(S).astype(np.float32)
    for lo in range(0, N, CHUNK):
        hi = min(N, lo + CHUNK)
        w = W2[:, lo:hi].astype(np.float32, copy=False)
        a = outer.T @ w  # (6, n)
        r = St @ (w * I2[:, lo:hi])  # (3, n)
        out[lo:hi] = _solve_sym3(a, r, fallback=P @ I2[:, lo:hi])
    if c != 1.0:
        out *= np.float32(c)
    return out.reshape(H, W, 3)


def _pow2(scale) -> float:
    """The power of two nearest to 1 / ``scale`` (1.0 for scales near 1, 0 or non-finite):
    multiplying by it is exact in floating point."""
    scale = float(scale)
    if not np.isfinite(scale) or scale <= 0.0:
        return 1.0
    e = int(np.round(np.log2(scale)))
    return 1.0 if e == 0 else float(2.0 ** -e)


def _solve_sym3(a, r, fallback):
    x, ok, _, _ = sym3_solve(a, r)
    if not ok.all():
        bad = ~ok
        x[bad] = fallback[:, bad].T
    return x


def split(b, *, eps=1e-6):
    """Split rho * n into unit normals and albedo.

    Pixels whose albedo is at most ``eps`` times the mean albedo (all intensities about
    zero, relative to the data's own scale) get the normal (0, 0, 1) and albedo 0, as
    the thesis prescribes (Section 3.2). The cut-off is relative so that images in any
    unit (x 1e-6, or under lights of power 1e30) give the same normals; the norm is
    computed without overflow or underflow for any finite float32 ``b``.

    Returns
    -------
    normals : (H, W, 3) float32
    albedo : (H, W) float32
    """
    rho = _norm3(b)
    with np.errstate(over="ignore", invalid="ignore"):
        ref = float(rho.mean()) if rho.size else 0.0   # one pass; NaN/inf propagate
    if not np.isfinite(ref):                            # only then the masked mean
        fin = np.isfinite(rho)
        ref = float(np.mean(rho, where=fin, dtype=np.float64)) if fin.any() else 0.0
    cut = np.float32(eps * ref) if np.isfinite(ref) else np.float32(0.0)
    bad = rho <= cut
    inv = np.where(bad, np.float32(1.0), rho)
    np.divide(np.float32(1.0), inv, out=inv)
    n = b * inv[..., None]
    if bad.any():
        n[bad] = (0.0, 0.0, 1.0)
        rho[bad] = 0.0
    return n, rho.astype(np.float32, copy=False)


def _norm3(b):
    """|b| over the last axis, float32: one pass normally; rescaled by a power of two
    (exact) when the squares would overflow (|b| > ~1e19) or lose precision to
    underflow (|b| < ~1e-17)."""
    # one pass over b (no (H, W, 3) temporary); ~2x faster than b * b summed by slices
    with np.errstate(over="ignore", under="ignore"):
        rho2 = np.einsum("...c,...c->...", b, b)
    top = float(np.max(rho2, initial=0.0)) if rho2.size else 0.0
    if np.isfinite(top) and (top > 1e-30 or (top == 0.0 and not b.any())):  # max keeps NaN/inf
        return np.sqrt(rho2, out=rho2)
    amax = np.abs(b).max(initial=0.0, where=np.isfinite(b))
    c = np.float32(_pow2(amax))
    bs = b * c
    rho = np.sqrt(np.einsum("...c,...c->...", bs, bs))
    rho /= c
    return rho


def lambert(b, S):
    """Lambert images rho * s_i . n (no clamping), Eq. 3.14.

    Parameters
    ----------
    b : (*P, 3) float32
        rho * n on any pixel layout ((H, W, 3) or flat (N, 3)).
    S : (k, 3) array_like

    Returns
    -------
    (k, *P) float32
    """
    P = b.shape[:-1]
    S = np.asarray(S, dtype=np.float32)
    return (S @ b.reshape(-1, 3).T).reshape((S.shape[0],) + P)


def residuals(images, b, S):
    """Signed residuals I - rho s.n for every observation, (k, *P) float32 (Eq. 3.1);
    ``images`` (k, *P), ``b`` (*P, 3)."""
    return images - lambert(b, S)


def residual_norm(images, b, S, valid=None, *, step=16384):
    """sqrt(sum_i valid_i (I_i - s_i . b)^2) per pixel, float32 of shape ``images.shape[1:]``.

    ``images`` (k, *P) with ``b`` (*P, 3); ``valid`` (k, *P) bool or None (all
    observations). Chunked over pixels so the (k, step) block stays in cache.
    """
    k = images.shape[0]
    P = images.shape[1:]
    I2 = images.reshape(k, -1)
    B = b.reshape(-1, 3)
    S32 = np.asarray(S, dtype=np.float32)
    V = None if valid is None else valid.reshape(k, -1)
    N = I2.shape[1]
    out = np.empty(N, dtype=np.float32)

    def block(lo, hi, dtype):
        r = I2[:, lo:hi].astype(dtype, copy=False) - S32.astype(dtype) @ B[lo:hi].T.astype(dtype)
        r *= r
        if V is not None:
            r *= V[:, lo:hi]
        return r.sum(axis=0)

    with np.errstate(over="ignore", under="ignore", invalid="ignore"):
        for lo in range(0, N, step):
            hi = min(N, lo + step)
            out[lo:hi] = block(lo, hi, np.float32)
    if _out_of_range(out):   # squares beyond float32 (|I| > ~1e19 or < ~1e-15): float64
        for lo in range(0, N, step):
            hi = min(N, lo + step)
            out[lo:hi] = np.sqrt(block(lo, hi, np.float64))
        return out.reshape(P)
    np.sqrt(out, out=out)
    return out.reshape(P)


def _out_of_range(sq) -> bool:
    """True when sums of squares overflowed float32 or are so small that their
    squares lost precision (then they are recomputed in float64)."""
    top = float(np.max(sq, initial=0.0))
    return not np.isfinite(top) or 0.0 < top < 1e-30


def ls_residual_norm(images, S):
    """Residual norm of the unmasked least-squares solution, (H, W) float32, exactly,
    from the coordinates of I in an orthonormal basis of null(S^T):
    |I - S S^+ I| = |U_perp^T I| (no solve needed)."""
    k, H, W = images.shape
    if k == 3:
        return np.zeros((H, W), dtype=np.float32)
    U = np.linalg.svd(np.asarray(S, dtype=np.float64), full_matrices=True)[0][:, 3:]
    U = np.ascontiguousarray(U.T, dtype=np.float32)  # (k - 3, k)
    I2 = images.reshape(k, -1)
    N = I2.shape[1]
    out = np.empty(N, dtype=np.float32)
    step = 4096  # keeps the (k - 3, step) block in cache
    X = np.empty((k - 3, step), dtype=np.float32)
    with np.errstate(over="ignore", under="ignore"):
        for lo in range(0, N, step):
            hi = min(N, lo + step)
            Xv = X[:, :hi - lo]
            np.matmul(U, I2[:, lo:hi], out=Xv)
            Xv *= Xv
            Xv.sum(axis=0, out=out[lo:hi])
    if _out_of_range(out):   # squares beyond float32: float64 (rare, extreme scales)
        U64 = U.astype(np.float64)
        for lo in range(0, N, step):
            hi = min(N, lo + step)
            x = U64 @ I2[:, lo:hi].astype(np.float64)
            out[lo:hi] = np.sqrt(np.einsum("ij,ij->j", x, x))
        return out.reshape(H, W)
    np.sqrt(out, out=out)
    return out.reshape(H, W)


def complete_three(valid, residual):
    """Eq. 3.1's rule: where fewer than three observations are valid, add the masked
    ones with the least absolute residual until three are used.

    Parameters
    ----------
    valid : (k, H, W) bool
    residual : (k, H, W) float
        Residuals of the unmasked least-squares solution (absolute value is used).

    Returns
    -------
    valid : (k, H, W) bool (a copy where anything changed)
    """
    count = valid.sum(axis=0)
    short = count < 3
    if not short.any():
        return valid
    valid = valid.copy()
    r = np.abs(residual[:, short]).astype(np.float32)
    v = valid[:, short]
    r[v] = -np.inf  # already-valid observations sort first
    order = np.argsort(r, axis=0, kind="stable")[:3]
    cols = np.arange(v.shape[1])
    for j in range(3):
        v[order[j], cols] = True
    valid[:, short] = v
    return valid
