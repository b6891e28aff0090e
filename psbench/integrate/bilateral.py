"""Bilateral normal integration (Cao, Santo, Shi, Okura & Matsushita, ECCV 2022).

Poisson integration asks every pair of neighbours to agree with the mean of their two
gradients, so a height jump -- a firing-pin wall seen at 4.9 µm per pixel -- is spread
over its neighbourhood. Bilateral normal integration (BiNI) keeps, at each pixel and
along each axis, two one-sided equations (to the next and to the previous neighbour)
and weights them by how continuous the surface is on that side:

    E(z) = sum_p  w_u(p) r_u+(p)^2 + (1 - w_u(p)) r_u-(p)^2
                + w_v(p) r_v+(p)^2 + (1 - w_v(p)) r_v-(p)^2,

with the residuals written without dividing by n_z (orthographic case), e.g.
``r_u+(p) = n_z(p) (z(p + e_u) - z(p)) + n_x(p)``, and the weights the sigmoid
``w_u = 1 / (1 + exp(-k ((n_z d_u- z)^2 - (n_z d_u+ z)^2)))``: the side with the smaller
height difference is trusted. Iteratively reweighted least squares alternates a sparse
linear solve for z (weights fixed) with a weight update, starting from w = 1/2
(a Poisson-like solution), until the energy changes by less than ``tol`` relatively.

Implementation notes (psbench, not the authors' code): the normal equations are the
weighted graph Laplacian of the 4-neighbour edges (each edge collects the two one-sided
terms that span it), assembled as a 5-diagonal ``scipy.sparse.dia_array`` on the mask's
bounding box; each solve is ``scipy.sparse.linalg.cg`` warm-started from the previous
heights and preconditioned with the Neumann-Laplacian DCT solve (``scipy.fft.dctn``).
Where a pixel has a neighbour on one side only, that side's equation gets the full
weight. Frame as :mod:`psbench.integrate`: x right, y up (``y = -row``), heights in
pixel units, ``dz/dcol = -n_x / n_z``, ``dz/drow = n_y / n_z``.
"""
from __future__ import annotations

import numpy as np
import scipy.fft as sfft
from scipy import ndimage, sparse
from scipy.sparse.linalg import LinearOperator, cg

from .._shared.checks import PsbenchError, as_mask
from .._shared.deprecation import renamed_args

__all__ = ["bilateral_integrate"]


def _sigmoid(x, k):
    return 0.5 * (1.0 + np.tanh(0.5 * k * x))     # = 1 / (1 + exp(-k x)), no overflow


def _dct_solver(H, W, scale):
    """Preconditioner: inverse of ``scale`` x the Neumann grid Laplacian (zero mode 0)."""
    ey = 2.0 - 2.0 * np.cos(np.pi * np.arange(H) / H)
    ex = 2.0 - 2.0 * np.cos(np.pi * np.arange(W) / W)
    lam = (ey[:, None] + ex[None, :]) * scale
    lam[0, 0] = np.inf

    lam = lam.astype(np.float32)

    def solve(r):
        c = sfft.dctn(r.reshape(H, W), type=2, norm="ortho", workers=-1)
        c /= lam
        return sfft.idctn(c, type=2, norm="ortho", workers=-1).ravel()

    return LinearOperator((H * W, H * W), matvec=solve, dtype=np.float32)


@renamed_args(positional=("object_mask",))
def bilateral_integrate(normals, *, object_mask=None, k=2.0, max_iter=150, tol=1e-4,
                        cg_tol=1e-3, cg_maxiter=500, datum="min", return_info=False):
    """Discontinuity-preserving integration of a normal map into heights.

    Parameters
    ----------
    normals : (H, W, 3) array_like
        Normals (unit or albedo-scaled; only directions are used), finite.
    object_mask : (H, W) bool, optional
        Pixels to integrate (default all). Edges leaving it are not used. Passing it
        positionally still works, with a DeprecationWarning.
    k : float, default 2
        Sharpness of the sigmoid weights (the authors' default); larger cuts
        discontinuities more readily. Heights are in pixel units.
    max_iter : int, default 150
        Maximum reweighting rounds (the authors' default).
    tol : float, default 1e-4
        Stop when the energy changes by less than this fraction between rounds.
    cg_tol : float, default 1e-3
        Relative residual of each conjugate-gradient solve.
    cg_maxiter : int, default 500
    datum : {"min", "mean"}
        Height origin per connected component of ``object_mask``: minimum 0 or mean 0.
    return_info : bool, default False
        Also return a dict: ``iterations``, ``energy`` (per round), ``cg_iterations``,
        ``wu``, ``wv`` ((H, W) final weights of the right / lower neighbour).

    Returns
    -------
    height : (H, W) float32
        Heights in pixel units, 0 outside ``object_mask``.
    info : dict
        Only with ``return_info``.
    """
    n = np.asarray(normals)
    if n.ndim != 3 or n.shape[2] != 3 or min(n.shape[:2]) < 2:
        raise PsbenchError(f"normals must have shape (H, W, 3) with H, W >= 2, got {n.shape}")
    if not np.isfinite(n).all():
        raise PsbenchError("normals hold NaN/inf values; clean or mask them first")
    m_full = as_mask(object_mask, n.shape[:2], "object_mask")
    for name, v, lo in (("k", k, 0.0), ("tol", tol, 0.0), ("cg_tol", cg_tol, 0.0)):
        if not (np.isfinite(float(v)) and float(v) > lo):
            raise PsbenchError(f"{name} must be a finite number > 0, got {v!r}")
    for name, v in (("max_iter", max_iter), ("cg_maxiter", cg_maxiter)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < 1:
            raise PsbenchError(f"{name} must be an integer >= 1, got {v!r}")
    if datum not in ("min", "mean"):
        raise PsbenchError(f"datum={datum!r} is not known; valid choices: min, mean")
    Hf, Wf = m_full.shape
    out = np.zeros((Hf, Wf), np.float32)
    info = {"iterations": 0, "energy": [], "cg_iterations": [],
            "wu": np.full((Hf, Wf), 0.5, np.float32), "wv": np.full((Hf, Wf), 0.5, np.float32)}
    if not m_full.any():
        return (out, info) if return_info else out
    rows, cols = np.flatnonzero(m_full.any(1)), np.flatnonzero(m_full.any(0))
    box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    # the working grid is the mask's bounding box grown to lengths the DCT is fast at
    # (the extra pixels lie off the mask)
    Hb, Wb = rows[-1] + 1 - rows[0], cols[-1] + 1 - cols[0]
    H, W = sfft.next_fast_len(int(Hb), real=True), sfft.next_fast_len(int(Wb), real=True)
    m = np.zeros((H, W), bool)
    m[:Hb, :Wb] = m_full[box]
    v = np.zeros((H, W, 3))
    v[..., 2] = 1.0
    v[:Hb, :Wb] = n[box]
    v = v / np.maximum(np.linalg.norm(v, axis=2, keepdims=True), 1e-12)
    nx, ny, nz = v[..., 0], v[..., 1], np.maximum(v[..., 2], 1e-3)
    er = m[:, :-1] & m[:, 1:]                       # edge to the right neighbour
    ed = m[:-1, :] & m[1:, :]                       # edge to the lower neighbour
    has_r, has_l = np.zeros_like(m), np.zeros_like(m)
    has_r[:, :-1], has_l[:, 1:] = er, er
    has_d, has_u = np.zeros_like(m), np.zeros_like(m)
    has_d[:-1, :], has_u[1:, :] = ed, ed
    # one-sided targets: r = nz dz + t, t = nx along columns and -ny along rows
    tu, tv = nx, -ny
    nz2 = nz * nz

    def one_sided(w, has_plus, has_minus):
        w = np.where(has_plus & ~has_minus, 1.0, w)
        return np.where(has_minus & ~has_plus, 0.0, w)

    wu = one_sided(np.full((H, W), 0.5), has_r, has_l)
    wv = one_sided(np.full((H, W), 0.5), has_d, has_u)
    z = np.zeros(H * W, np.float32)
    N = H * W
    energy_old = None
    for it in range(int(max_iter)):
        # edge weights c and c * target, both one-sided terms that span the edge
        c_r = (wu[:, :-1] * nz2[:, :-1] + (1 - wu[:, 1:]) * nz2[:, 1:]) * er
        b_r = -(wu[:, :-1] * nz[:, :-1] * tu[:, :-1] + (1 - wu[:, 1:]) * nz[:, 1:] * tu[:, 1:]) * er
        c_d = (wv[:-1, :] * nz2[:-1, :] + (1 - wv[1:, :]) * nz2[1:, :]) * ed
        b_d = -(wv[:-1, :] * nz[:-1, :] * tv[:-1, :] + (1 - wv[1:, :]) * nz[1:, :] * tv[1:, :]) * ed
        diag = np.zeros((H, W))
        diag[:, :-1] += c_r
        diag[:, 1:] += c_r
        diag[:-1, :] += c_d
        diag[1:, :] += c_d
        rhs = np.zeros((H, W))
        rhs[:, 1:] += b_r
        rhs[:, :-1] -= b_r
        rhs[1:, :] += b_d
        rhs[:-1, :] -= b_d
        scale = float(diag[m].mean()) / 4.0 if m.any() else 1.0
        diag = diag + 1e-10 * scale     # rows off the mask ~0: decoupled, ignored (as in integrate)
        off_r = np.zeros((H, W))
        off_r[:, :-1] = -c_r
        off_d = np.zeros((H, W))
        off_d[:-1, :] = -c_d
        fr, fd = off_r.ravel(), off_d.ravel()
        # dia layout: entry (i, i + o) of offset o is stored in column i + o
        A = sparse.dia_array((np.vstack([fd, fr, diag.ravel(), np.r_[0.0, fr[:-1]],
                                         np.r_[np.zeros(W), fd[:-W]]]).astype(np.float32),
                              [-W, -1, 0, 1, W]), shape=(N, N))
        count = [0]

        def tick(_):
            count[0] += 1

        # float32 solve: the relative residual asked for (1e-3) is far above its epsilon
        z, _ = cg(A, rhs.ravel().astype(np.float32), x0=z, rtol=cg_tol,
                  maxiter=int(cg_maxiter), M=_dct_solver(H, W, scale), callback=tick)
        z = z.astype(np.float32)
        info["cg_iterations"].append(count[0])
        Z = z.reshape(H, W)
        dr = np.zeros((H, W))
        dr[:, :-1] = (Z[:, 1:] - Z[:, :-1]) * er
        dl = np.zeros((H, W))
        dl[:, 1:] = dr[:, :-1]
        dd = np.zeros((H, W))
        dd[:-1, :] = (Z[1:, :] - Z[:-1, :]) * ed
        du = np.zeros((H, W))
        du[1:, :] = dd[:-1, :]
        wu = one_sided(_sigmoid(nz2 * (dl * dl - dr * dr), k), has_r, has_l)
        wv = one_sided(_sigmoid(nz2 * (du * du - dd * dd), k), has_d, has_u)
        energy = float(np.sum(m * (wu * has_r * (nz * dr + tu) ** 2
                                   + (1 - wu) * has_l * (nz * dl + tu) ** 2
                                   + wv * has_d * (nz * dd + tv) ** 2
                                   + (1 - wv) * has_u * (nz * du + tv) ** 2)))
        info["energy"].append(energy)
        info["iterations"] = it + 1
        if energy_old is not None and abs(energy - energy_old) <= tol * max(energy_old, 1e-300):
            break
        energy_old = energy
    Z = z.reshape(H, W)[:Hb, :Wb]
    m, wu, wv = m[:Hb, :Wb], wu[:Hb, :Wb], wv[:Hb, :Wb]
    lab, ncomp = ndimage.label(m)
    idx = np.arange(1, ncomp + 1)
    ref = (ndimage.minimum(Z, lab, idx) if datum == "min" else ndimage.mean(Z, lab, idx))
    Z = np.where(m, Z - np.r_[0.0, np.asarray(ref, float)][lab], 0.0)
    out[box] = Z
    info["wu"][box] = np.where(m, wu, 0.5)
    info["wv"][box] = np.where(m, wv, 0.5)
    return (out, info) if return_info else out
