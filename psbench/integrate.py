"""Normals -> heights: Frankot–Chellappa and (masked) Poisson integration.

Frame and gradients (DESIGN.md): x right, y up (``y = -row``), camera at +z,
heights in pixel units. A unit normal ``n = (nx, ny, nz)`` of the surface
``z(x, y)`` gives

    p = dz/dx = -nx / nz,    q = dz/dy = -ny / nz,
    dz/dcol = p,             dz/drow = -q.

``nz`` is clamped to at least :data:`NZ_MIN` (0.05, i.e. slopes up to ~87°)
before dividing, so gradients stay finite (|p|, |q| <= 20 for unit normals) at
silhouettes and for back-facing noisy estimates.

Methods
-------
``"poisson"`` (default)
    Least-squares integration on the pixel grid solved in closed form with the
    DCT (Neumann boundary at the frame). Every pair of 4-neighbours is an edge
    whose target height difference is the mean of the two pixels' gradients.
    Edges that do not have both pixels inside ``mask`` get the target 0, so the
    background is a flat, free membrane: it cannot tilt or pull the object, it
    only ties separate objects (e.g. several spheres on a plane) to one common
    base level. Cost: one ``dctn`` + one ``idctn`` (float64).
``"poisson-sparse"``
    The exact masked least-squares problem: only edges with both pixels inside
    ``mask`` are used (the background plays no part), solved with a sparse
    direct solver. Slower (seconds at 512²) but free of the membrane's small
    pull where silhouette heights vary. Each connected component of the mask
    is integrated on its own; its offset is undetermined, so every component
    is shifted to have its own minimum at 0.
``"fc"``
    Frankot–Chellappa: projection of the gradient field onto integrable Fourier
    modes. The gradients are mirrored to a (2H, 2W) periodic field (even
    extension of the height) to avoid wrap-around artefacts at the frame.
    Outside ``mask`` gradients are 0, as for ``"poisson"``.

Height datum
------------
``datum="min"`` (default): the minimum over the mask is 0.
``datum="mean"``: the mean over the mask is 0.
Pixels outside the mask are set to 0 (the base plane) in both cases.
"""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft

from ._checks import PsbenchError, as_mask, choice

__all__ = ["integrate", "gradients", "METHODS", "NZ_MIN"]

#: integration methods accepted by :func:`integrate`
METHODS = ("poisson", "fc", "poisson-sparse")
#: lower clamp on n_z when converting normals to gradients
NZ_MIN = 0.05


def _check_normals(normals):
    n = np.asarray(normals)
    if n.ndim != 3 or n.shape[2] != 3:
        raise PsbenchError(f"normals must have shape (H, W, 3), got {n.shape}")
    if not np.issubdtype(n.dtype, np.number) or np.issubdtype(n.dtype, np.complexfloating):
        raise PsbenchError(f"normals must be a real numeric array, got dtype {n.dtype}")
    if n.shape[0] < 2 or n.shape[1] < 2:
        raise PsbenchError(f"normals must be at least 2x2 pixels, got {n.shape}")
    if not np.isfinite(n).all():
        bad = int((~np.isfinite(n)).any(axis=-1).sum())
        raise PsbenchError(f"normals hold NaN/inf at {bad} pixels; clean or mask them first")
    return n


def gradients(normals, mask=None, *, nz_min=NZ_MIN):
    """Height gradients from normals in image axes.

    Parameters
    ----------
    normals : (H, W, 3) array_like
        Normals (need not be unit; only ratios are used).
    mask : (H, W) bool, optional
        Object mask; gradients outside it are 0.
    nz_min : float
        Lower clamp on ``nz`` (relative to ``|n|``).

    Returns
    -------
    gcol, grow : (H, W) float64
        ``dz/dcol = p = -nx/nz`` and ``dz/drow = -q = ny/nz``.
    """
    n = np.asarray(normals, dtype=np.float64)
    length = np.sqrt(np.einsum("...i,...i->...", n, n))
    ok = length > 0
    scale = np.where(ok, 1.0 / np.where(ok, length, 1.0), 0.0)
    nx = n[..., 0] * scale
    ny = n[..., 1] * scale
    nz = np.maximum(n[..., 2] * scale, nz_min)
    gcol = -nx / nz
    grow = ny / nz
    if mask is not None:
        gcol = np.where(mask, gcol, 0.0)
        grow = np.where(mask, grow, 0.0)
    return gcol, grow


def _edge_targets(gcol, grow, mask):
    """Target differences on horizontal (H, W-1) and vertical (H-1, W) edges."""
    ex = 0.5 * (gcol[:, 1:] + gcol[:, :-1])
    ey = 0.5 * (grow[1:, :] + grow[:-1, :])
    if mask is not None:
        ex = np.where(mask[:, 1:] & mask[:, :-1], ex, 0.0)
        ey = np.where(mask[1:, :] & mask[:-1, :], ey, 0.0)
    return ex, ey


def _divergence(ex, ey, shape):
    """D^T g for forward-difference edges: the right-hand side of L z = D^T g."""
    H, W = shape
    d = np.zeros((H, W), dtype=np.float64)
    d[:, :-1] -= ex
    d[:, 1:] += ex
    d[:-1, :] -= ey
    d[1:, :] += ey
    return d


_EIG_CACHE: dict = {}


def _neumann_eigs(H, W):
    key = (H, W)
    lam = _EIG_CACHE.get(key)
    if lam is None:
        ly = 4.0 * np.sin(np.pi * np.arange(H) / (2.0 * H)) ** 2
        lx = 4.0 * np.sin(np.pi * np.arange(W) / (2.0 * W)) ** 2
        lam = ly[:, None] + lx[None, :]
        lam[0, 0] = 1.0  # DC: free constant, set to 0 below
        if len(_EIG_CACHE) > 8:
            _EIG_CACHE.clear()
        _EIG_CACHE[key] = lam
    return lam


def _poisson_dct(gcol, grow, mask):
    H, W = gcol.shape
    ex, ey = _edge_targets(gcol, grow, mask)
    div = _divergence(ex, ey, (H, W))
    # The grid Laplacian with free (Neumann) ends is diagonal in the DCT-II basis.
    c = sfft.dctn(div, type=2, norm="ortho", workers=-1, overwrite_x=True)
    c /= _neumann_eigs(H, W)
    c[0, 0] = 0.0
    return sfft.idctn(c, type=2, norm="ortho", workers=-1, overwrite_x=True)


def _fc(gcol, grow):
    H, W = gcol.shape
    # even extension of z  <=>  d/dcol odd in col, even in row (and vice versa)
    gc = np.block([[gcol, -gcol[:, ::-1]], [gcol[::-1, :], -gcol[::-1, ::-1]]])
    gr = np.block([[grow, grow[:, ::-1]], [-grow[::-1, :], -grow[::-1, ::-1]]])
    H2, W2 = 2 * H, 2 * W
    Gc = sfft.rfft2(gc, workers=-1)
    Gr = sfft.rfft2(gr, workers=-1)
    wr = 2.0 * np.pi * sfft.fftfreq(H2)[:, None]
    wc = 2.0 * np.pi * sfft.rfftfreq(W2)[None, :]
    den = wr ** 2 + wc ** 2
    den[0, 0] = 1.0
    Z = (-1j * wc * Gc - 1j * wr * Gr) / den
    Z[0, 0] = 0.0
    z = sfft.irfft2(Z, s=(H2, W2), workers=-1)
    return z[:H, :W]


def _poisson_sparse(gcol, grow, mask):
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components
    from scipy.sparse.linalg import spsolve

    H, W = gcol.shape
    if mask is None:
        mask = np.ones((H, W), dtype=bool)
    ex, ey = _edge_targets(gcol, grow, mask)
    idx = -np.ones((H, W), dtype=np.int64)
    n = int(mask.sum())
    idx[mask] = np.arange(n)
    z = np.zeros((H, W), dtype=np.float64)
    if n == 0:
        return z
    mx = mask[:, 1:] & mask[:, :-1]
    my = mask[1:, :] & mask[:-1, :]
    a = np.concatenate([idx[:, :-1][mx], idx[:-1, :][my]])  # edge tail
    b = np.concatenate([idx[:, 1:][mx], idx[1:, :][my]])    # edge head
    g = np.concatenate([ex[mx], ey[my]])                     # z[b] - z[a] ~ g
    m = a.size
    rows = np.arange(m)
    D = sp.csr_matrix((np.r_[-np.ones(m), np.ones(m)], (np.r_[rows, rows], np.r_[a, b])),
                      shape=(m, n))
    L = (D.T @ D).tocsr()
    rhs = D.T @ g
    ncomp, label = connected_components(L, directed=False)
    # pin the first pixel of every component (removes the constant null space)
    first = np.unique(label, return_index=True)[1]
    keep = np.ones(n, dtype=bool)
    keep[first] = False
    sol = np.zeros(n)
    if keep.any():
        Lk = L[keep][:, keep].tocsc()
        sol[keep] = spsolve(Lk, rhs[keep])
    # every component's minimum at 0
    mins = np.full(ncomp, np.inf)
    np.minimum.at(mins, label, sol)
    sol -= mins[label]
    z[mask] = sol
    return z


def integrate(normals, mask=None, *, method="poisson", datum="min", nz_min=NZ_MIN):
    """Integrate a normal map into a height map.

    Parameters
    ----------
    normals : (H, W, 3) array_like
        Surface normals (unit or albedo-scaled; only ratios are used), frame
        x right, y up, camera at +z. Must be finite.
    mask : (H, W) bool, optional
        Object mask. Gradients outside it (and on edges crossing its boundary)
        are ignored. None: the whole frame.
    method : {"poisson", "fc", "poisson-sparse"}
        See the module docstring. "poisson" (DCT, Neumann) is fast: one
        forward and one inverse DCT.
    datum : {"min", "mean"}
        Height origin over the mask: minimum at 0 (default) or mean 0.
    nz_min : float
        Clamp ``nz >= nz_min`` (after normalising) when forming gradients.

    Returns
    -------
    height : (H, W) float32
        Heights in pixel units (z up towards the camera), 0 outside the mask.
    """
    n = _check_normals(normals)
    choice(method, METHODS, "method")
    choice(datum, ("min", "mean"), "datum")
    if not (0 < float(nz_min) <= 1):
        raise PsbenchError(f"nz_min must be in (0, 1], got {nz_min}")
    H, W = n.shape[:2]
    m = None if mask is None else as_mask(mask, (H, W), "mask")
    if m is not None and not m.any():
        return np.zeros((H, W), dtype=np.float32)
    if m is not None and m.all():
        m = None
    gcol, grow = gradients(n, m, nz_min=float(nz_min))
    if method == "poisson":
        z = _poisson_dct(gcol, grow, m)
    elif method == "fc":
        z = _fc(gcol, grow)
    else:
        z = _poisson_sparse(gcol, grow, m)
    inside = np.ones((H, W), dtype=bool) if m is None else m
    if method != "poisson-sparse" or datum == "mean":
        zi = z[inside]
        z = z - (zi.min() if datum == "min" else zi.mean())
    if m is not None:
        z = np.where(m, z, 0.0)
    return z.astype(np.float32)
