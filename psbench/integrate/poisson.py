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
All Poisson variants solve the least-squares problem on the pixel grid: every
pair of 4-neighbours is an edge whose target height difference is the mean of
the two pixels' gradients (exact for planes); an edge is used only when both
pixels are inside ``object_mask``.

``"poisson"`` (default)
    The exact masked least-squares solution. Without an object mask (or a full one) it
    is one DCT solve (Neumann boundary at the frame: ``scipy.fft.dctn`` /
    ``idctn``). Under a mask the Laplacian of the in-mask edges is no longer
    DCT-diagonal; it is solved by conjugate gradients preconditioned with the
    full-grid DCT solve and warm-started from ``"poisson-dct"``: typically
    5-30 iterations (convex silhouettes converge fastest; slits and thin
    necks slowest), stopping at ``tol`` relative residual (``tol=1e-4``: height
    errors of a few hundredths of a pixel). Mask components of at most
    :data:`SMALL_COMPONENT` pixels are solved directly (sparse LU), and so is
    a ragged mask on which CG does not converge within ``maxiter``.
``"poisson-dct"``
    One DCT solve where edges outside the mask or across its boundary get the
    target 0: the background is a flat, free membrane. Fastest, and exact
    without a mask, but the membrane pulls silhouettes towards one level
    (a tilted disc loses ~10-20 % of its tilt), so use it only where speed
    matters more than shape.
``"poisson-sparse"``
    The same exact masked problem as ``"poisson"``, solved with a sparse
    direct solver (``scipy.sparse.linalg.spsolve``). Slow (seconds at 512²);
    a reference for tests.
``"bilateral"``
    Bilateral normal integration (Cao et al., ECCV 2022), :mod:`psbench._bilateral`:
    per-edge sigmoid weights let the height jump where the two one-sided gradient
    estimates disagree, so steep walls and steps are kept; one sparse system per
    reweighting round (conjugate gradients with a DCT Poisson preconditioner).
    Tens of times the cost of ``"poisson"``.
``"fc"``
    Frankot–Chellappa: projection of the gradient field onto integrable Fourier
    modes (continuous frequencies). Gradients are mirrored to a (2H, 2W)
    periodic field (even extension of the height) to avoid wrap-around
    artefacts at the frame. Outside ``object_mask`` the gradients are 0, so it has
    the membrane bias of ``"poisson-dct"`` under a mask.

Separate components of the object mask share no edge, so their relative offsets are not
fixed by the normals: the exact methods shift every 4-connected component so
that its own minimum is 0 (objects resting on a common base plane) before the
datum is applied.

Only the object mask's bounding box (plus a one-pixel frame) is processed.

Height datum
------------
``datum="min"`` (default): the minimum over the object mask is 0.
``datum="mean"``: the mean over the object mask is 0.
Pixels outside the object mask are set to 0 (the base plane) in both cases.
"""
from __future__ import annotations

import warnings

import numpy as np
import scipy.fft as sfft

from .._shared.checks import PsbenchError, as_mask, choice
from .._shared.deprecation import renamed_args, renamed_names
from .._shared.memory import managed_memory
from . import _cg_kernel as _cg

__all__ = ["integrate", "gradients", "INTEGRATORS", "NZ_MIN"]

#: integrators accepted by :func:`integrate` (formerly ``METHODS``)
INTEGRATORS = ("poisson", "poisson-dct", "fc", "poisson-sparse", "bilateral")
#: lower clamp on n_z when converting normals to gradients
NZ_MIN = 0.05


def _number(value, name) -> float:
    """A real, finite number (bools and strings refused)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be a number, got {value!r}") from None
    if isinstance(value, (bool, np.bool_, str)) or not np.isfinite(v):
        raise PsbenchError(f"{name} must be a finite number, got {value!r}")
    return v


def _check_normals(normals):
    try:
        n = np.asarray(normals)
    except (TypeError, ValueError):
        raise PsbenchError(f"normals must be an (H, W, 3) array, got {type(normals).__name__} "
                           "that numpy cannot stack") from None
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


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def gradients(normals, *, object_mask=None, nz_min=NZ_MIN):
    """Height gradients from normals in image axes.

    Parameters
    ----------
    normals : (H, W, 3) array_like
        Normals (need not be unit; only ratios are used).
    object_mask : (H, W) bool, optional
        Object region; gradients outside it are 0.
    nz_min : float
        Lower clamp on ``nz`` (relative to ``|n|``).

    Returns
    -------
    gcol, grow : (H, W) float64
        ``dz/dcol = p = -nx/nz`` and ``dz/drow = -q = ny/nz``.
    """
    n = np.asarray(normals, dtype=np.float32)
    nx, ny, nz = n[..., 0], n[..., 1], n[..., 2]
    length = np.sqrt(nx * nx + ny * ny + nz * nz)
    # clamp n_z / |n| >= nz_min without normalising (only ratios matter);
    # a zero vector gives zero gradients
    nzc = np.maximum(nz, np.float32(nz_min) * length)
    nzc[length == 0] = 1.0
    inv = np.reciprocal(nzc, dtype=np.float64)
    gcol = -nx * inv
    grow = ny * inv
    if object_mask is not None:
        gcol *= object_mask
        grow *= object_mask
    return gcol, grow


def _edge_targets(gcol, grow, object_mask):
    """Target differences on horizontal (H, W-1) and vertical (H-1, W) edges."""
    ex = 0.5 * (gcol[:, 1:] + gcol[:, :-1])
    ey = 0.5 * (grow[1:, :] + grow[:-1, :])
    if object_mask is not None:
        ex = np.where(object_mask[:, 1:] & object_mask[:, :-1], ex, 0.0)
        ey = np.where(object_mask[1:, :] & object_mask[:-1, :], ey, 0.0)
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


def _dct_solve(rhs, lam, dtype=np.float64):
    """Pseudo-inverse of the full-grid Neumann Laplacian (DC set to 0)."""
    c = sfft.dctn(rhs.astype(dtype, copy=False), type=2, norm="ortho", workers=-1)
    c /= lam.astype(dtype, copy=False)
    c[0, 0] = 0.0
    return sfft.idctn(c, type=2, norm="ortho", workers=-1, overwrite_x=True)


def _poisson_dct(gcol, grow, object_mask):
    """One DCT solve with zero targets on background / boundary edges (membrane)."""
    H, W = gcol.shape
    ex, ey = _edge_targets(gcol, grow, object_mask)
    div = _divergence(ex, ey, (H, W))
    # The grid Laplacian with free (Neumann) ends is diagonal in the DCT-II basis.
    # Single precision DCT: ~3e-4 px error on a 1200 px relief at 2048², below
    # the float32 resolution of the returned heights, at half the cost.
    return _dct_solve(div, _neumann_eigs(H, W), np.float32).astype(np.float64)


def _components(object_mask):
    """4-connected components of ``object_mask``: labels (H, W) int (0 = background), count."""
    from scipy import ndimage

    return ndimage.label(object_mask)


def _align_components(z, object_mask, *, label=None, ncomp=None):
    """Shift every 4-connected component of ``object_mask`` so that its minimum is 0.

    Separate components share no edge, so their relative offsets are not fixed
    by the normals; psbench assumes the objects rest on a common base plane.
    """
    if label is None:
        label, ncomp = _components(object_mask)
    if ncomp <= 1:
        return z
    lab = label[object_mask]
    mins = np.full(ncomp + 1, np.inf)
    np.minimum.at(mins, lab, z[object_mask])
    z = z.copy()
    z[object_mask] -= mins[lab]
    return z


def _dot(a, b):
    """Inner product without BLAS (threaded BLAS dot stalls on a loaded machine)."""
    return float(np.einsum("ij,ij->", a, b))


def _poisson_cg(gcol, grow, object_mask, *, tol, maxiter):
    """Exact masked least squares by conjugate gradients, DCT-preconditioned.

    Operator: Laplacian of the graph of in-mask edges (on the full grid; rows of
    background pixels are zero). Preconditioner: the full-grid Neumann Laplacian
    (one DCT pair). Start: the membrane solution of :func:`_poisson_dct`.
    Stops when ||r|| <= tol * ||b||. Component offsets are left as they come.

    The grid is padded with background to DCT-friendly sizes (2, 3, 5-smooth; a prime
    factor such as 277 in 1939 makes each DCT ~3x slower). Background pixels carry no
    edge, so the masked problem and its solution are the same; only the
    preconditioner and the warm start see the larger frame.

    Returns
    -------
    z : (H, W) float64
    iterations : int
    converged : bool
    """
    H0, W0 = gcol.shape
    H, W = sfft.next_fast_len(H0, real=True), sfft.next_fast_len(W0, real=True)
    if (H, W) != (H0, W0):
        pad = ((0, H - H0), (0, W - W0))
        gcol, grow = np.pad(gcol, pad), np.pad(grow, pad)
        object_mask = np.pad(object_mask, pad)
        z, it, ok = _poisson_cg(gcol, grow, object_mask, tol=tol, maxiter=maxiter)
        return z[:H0, :W0], it, ok
    ex, ey = _edge_targets(gcol, grow, object_mask)
    b = _divergence(ex, ey, (H, W))
    lam = _neumann_eigs(H, W)
    wx = (object_mask[:, 1:] & object_mask[:, :-1]).astype(np.float64)
    wy = (object_mask[1:, :] & object_mask[:-1, :]).astype(np.float64)

    def precond(r):
        return _dct_solve(r, lam, np.float32).astype(np.float64)

    z = _dct_solve(b, lam, np.float32).astype(np.float64)  # warm start: membrane solution
    Ad = np.empty_like(z)
    r = b - _cg.laplacian(z, wx, wy, Ad)
    nb = float(np.sqrt(_dot(b, b)))
    if nb == 0.0:
        return z, 0, True
    y = precond(r)
    d = y.copy()
    rz = float(_dot(r, y))
    it, converged = 0, bool(np.sqrt(_dot(r, r)) <= tol * nb)
    while not converged and it < maxiter:
        it += 1
        _cg.laplacian(d, wx, wy, Ad)
        dAd = float(_dot(d, Ad))
        if not dAd > 0:
            break
        a = rz / dAd
        _cg.step(z, r, d, Ad, a)   # z += a d; Ad *= a; r -= Ad
        if np.sqrt(_dot(r, r)) <= tol * nb:
            converged = True
            break
        y = precond(r)
        rz_new = float(_dot(r, y))
        _cg.direction(d, y, rz_new / rz)   # d = d (rz_new / rz) + y
        rz = rz_new
    return z, it, converged


#: components up to this many pixels are solved directly (sparse LU), larger by CG
SMALL_COMPONENT = 2048
#: if CG does not converge within ``maxiter``, masks up to this many pixels are
#: solved directly instead (larger ones keep the CG result with a warning)
SPARSE_FALLBACK = 1 << 20


def _poisson_exact(gcol, grow, object_mask, *, tol, maxiter):
    """Exact masked least squares: small components by sparse LU, the rest by CG."""
    label, ncomp = _components(object_mask)
    sizes = np.bincount(label.ravel(), minlength=ncomp + 1)
    small = sizes <= SMALL_COMPONENT
    small[0] = False
    z = np.zeros(object_mask.shape)
    in_small = small[label]
    if in_small.any():
        z += _poisson_sparse(gcol, grow, in_small)
    in_big = object_mask & ~in_small
    if in_big.any():
        zb, it, ok = _poisson_cg(gcol, grow, in_big, tol=tol, maxiter=maxiter)
        if not ok and in_big.sum() <= SPARSE_FALLBACK:
            # ragged masks (near-percolating holes, thin mazes) defeat the DCT
            # preconditioner; fall back to the direct solver
            zb = _poisson_sparse(gcol, grow, in_big)
        elif not ok:
            warnings.warn(f"integrate: conjugate gradients stopped after {it} iterations "
                          f"above tol={tol:g}; heights are approximate (raise maxiter or "
                          f"use integrator='poisson-sparse')", RuntimeWarning, stacklevel=4)
        z[in_big] = zb[in_big]
    return _align_components(z, object_mask, label=label, ncomp=ncomp)


def _fc(gcol, grow):
    H, W = gcol.shape
    # even extension of z  <=>  d/dcol odd in col, even in row (and vice versa)
    gcol = gcol.astype(np.float32)
    grow = grow.astype(np.float32)
    gc = np.block([[gcol, -gcol[:, ::-1]], [gcol[::-1, :], -gcol[::-1, ::-1]]])
    gr = np.block([[grow, grow[:, ::-1]], [-grow[::-1, :], -grow[::-1, ::-1]]])
    H2, W2 = 2 * H, 2 * W
    Gc = sfft.rfft2(gc, workers=-1)
    Gr = sfft.rfft2(gr, workers=-1)
    wr = (2.0 * np.pi * sfft.fftfreq(H2)[:, None]).astype(np.float32)
    wc = (2.0 * np.pi * sfft.rfftfreq(W2)[None, :]).astype(np.float32)
    den = wr ** 2 + wc ** 2
    den[0, 0] = 1.0
    Gc *= wc
    Gr *= wr
    Gc += Gr
    Gc *= np.complex64(-1j)
    Gc /= den
    Gc[0, 0] = 0.0
    z = sfft.irfft2(Gc, s=(H2, W2), workers=-1, overwrite_x=True)
    return z[:H, :W].astype(np.float64)


def _poisson_sparse(gcol, grow, object_mask):
    """Exact masked least squares with a sparse direct solver (reference method)."""
    import scipy.sparse as sp
    from scipy.sparse.csgraph import connected_components
    from scipy.sparse.linalg import spsolve

    H, W = gcol.shape
    ex, ey = _edge_targets(gcol, grow, object_mask)
    idx = -np.ones((H, W), dtype=np.int64)
    n = int(object_mask.sum())
    idx[object_mask] = np.arange(n)
    z = np.zeros((H, W), dtype=np.float64)
    if n == 0:
        return z
    mx = object_mask[:, 1:] & object_mask[:, :-1]
    my = object_mask[1:, :] & object_mask[:-1, :]
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
    z[object_mask] = sol
    return z


@managed_memory
@renamed_args(positional=("object_mask",),
              renamed={"mask": "object_mask", "method": "integrator"})
def integrate(normals, *, object_mask=None, integrator="poisson", datum="min", nz_min=NZ_MIN,
              tol=1e-4, maxiter=100):
    """Integrate a normal map into a height map.

    Parameters
    ----------
    normals : (H, W, 3) array_like
        Surface normals (unit or albedo-scaled; only ratios are used), frame
        x right, y up, camera at +z. Must be finite.
    object_mask : (H, W) bool, optional
        Object region. Gradients outside it and edges crossing its boundary are
        ignored. None: the whole frame.
    integrator : {"poisson", "poisson-dct", "fc", "poisson-sparse", "bilateral"}
        See the module docstring (formerly ``method=``, which still works with a
        warning). "poisson": exact masked least squares (one DCT solve without a
        mask, else DCT-preconditioned conjugate gradients). "poisson-dct": one DCT
        solve with a flat background membrane (fastest, biased under a mask). "fc":
        Frankot–Chellappa. "poisson-sparse": exact, sparse direct solver (slow
        reference). "bilateral": discontinuity-preserving
        bilateral normal integration (Cao et al., ECCV 2022; :mod:`psbench._bilateral`,
        its defaults; ``nz_min``, ``tol`` and ``maxiter`` do not apply), which keeps
        steep walls and steps that Poisson smooths, at tens of times its cost.
    datum : {"min", "mean"}
        Height origin over the mask: minimum at 0 (default) or mean 0.
    nz_min : float
        Clamp ``nz >= nz_min`` (after normalising) when forming gradients.
    tol, maxiter : float, int
        Stopping rule of the conjugate gradients of ``"poisson"`` under a mask:
        residual norm <= ``tol`` x right-hand-side norm, or ``maxiter`` steps.

    Returns
    -------
    height : (H, W) float32
        Heights in pixel units (z up towards the camera), 0 outside the mask.
    """
    n = _check_normals(normals)
    choice(integrator, INTEGRATORS, "integrator")
    choice(datum, ("min", "mean"), "datum")
    if not (0 < _number(nz_min, "nz_min") <= 1):
        raise PsbenchError(f"nz_min must be in (0, 1], got {nz_min}")
    if not (_number(tol, "tol") > 0):
        raise PsbenchError(f"tol must be > 0, got {tol}")
    if isinstance(maxiter, (bool, np.bool_)) or _number(maxiter, "maxiter") != int(maxiter) \
            or int(maxiter) < 1:
        raise PsbenchError(f"maxiter must be an integer >= 1, got {maxiter!r}")
    maxiter = int(maxiter)
    H, W = n.shape[:2]
    if integrator == "bilateral":
        from .bilateral import bilateral_integrate

        return bilateral_integrate(n, object_mask=object_mask, datum=datum)
    m = None if object_mask is None else as_mask(object_mask, (H, W), "object_mask")
    if m is not None and not m.any():
        return np.zeros((H, W), dtype=np.float32)
    if m is not None and m.all():
        m = None
    box = (slice(0, H), slice(0, W))
    if m is not None:
        # work on the mask's bounding box plus a one-pixel frame of background
        rows = np.flatnonzero(m.any(axis=1))
        cols = np.flatnonzero(m.any(axis=0))
        box = (slice(max(rows[0] - 1, 0), min(rows[-1] + 2, H)),
               slice(max(cols[0] - 1, 0), min(cols[-1] + 2, W)))
        n, m = n[box], m[box]  # at least 2x2 since H, W >= 2
    z = _integrate_box(n, m, integrator, float(nz_min), float(tol), int(maxiter))
    zi = z if m is None else z[m]
    z = z - (zi.min() if datum == "min" else zi.mean())
    if m is not None:
        z = np.where(m, z, 0.0)
    out = np.zeros((H, W), dtype=np.float32)
    out[box] = z
    return out


def _integrate_box(n, m, integrator, nz_min, tol, maxiter):
    gcol, grow = gradients(n, object_mask=m, nz_min=nz_min)
    if integrator == "poisson-dct" or (integrator == "poisson" and m is None):
        z = _poisson_dct(gcol, grow, m)
    elif integrator == "poisson":
        z = _poisson_exact(gcol, grow, m, tol=tol, maxiter=maxiter)
    elif integrator == "fc":
        z = _fc(gcol, grow)
    else:
        mm = np.ones(n.shape[:2], dtype=bool) if m is None else m
        z = _align_components(_poisson_sparse(gcol, grow, mm), mm)
    return z


__getattr__ = renamed_names(globals(), {"METHODS": "INTEGRATORS"})
