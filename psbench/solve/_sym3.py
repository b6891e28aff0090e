"""The symmetric 3x3 solve of every psbench kernel, and its one singularity rule.

Every per-pixel least-squares fit of rho * n ends in a symmetric 3x3 system
``A b = r`` with ``A = sum_i w_i s_i s_i^T`` (w_i >= 0, so A is positive semi-definite).
It is solved in closed form by the adjugate: ``b = adj(A) r / det(A)``. ``A`` counts as
singular when

    |det A| <= RCOND * trace(A)^3,

a test that does not depend on the scale of the lights or the weights (det scales as
trace^3). The held-out errors use the same test with ``HELDOUT_RCOND``. Every A whose smallest eigenvalue is at most RCOND * trace fails it
(det <= lambda_min trace^2).

The algebra is written once, in :func:`_cofactors`, a plain function of six entries
that runs on numpy arrays (one entry per pixel) and, compiled by numba and inlined, on
scalars inside the compiled kernels:

- :func:`sym3_cofactors` / :func:`sym3_solve`: numpy, over arrays of pixels;
- :func:`solve_sym3` / :func:`inv_sym3`: numba, one pixel (``inline="always"``, so a
  kernel's pixel loop keeps the arithmetic in registers).
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["RCOND", "HELDOUT_RCOND", "sym3_cofactors", "sym3_solve", "solve_sym3", "inv_sym3"]

#: A is singular when |det A| <= RCOND * trace(A)^3
RCOND = 1e-6
#: the held-out errors (:mod:`psbench.solve._heldout_kernel`) accept down to 1e-9: their
#: float64 sums of the fit's normal matrix are reliable there, and the regression gate's
#: validation errors were measured with it (with RCOND, held-out errors of a few
#: near-singular pixels become NaN and stress's "clipped at 50 %" l1 cell moves by 0.0013)
HELDOUT_RCOND = 1e-9


def _cofactors(a00, a01, a02, a11, a12, a22, rcond=RCOND):
    """Cofactors (the adjugate's 6 unique entries), determinant and non-singularity."""
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    tr = a00 + a11 + a22
    ok = abs(det) > rcond * tr * tr * tr
    return c00, c01, c02, c11, c12, c22, det, ok


_cofactors_1 = njit(cache=True, nogil=True, inline="always", error_model="numpy")(_cofactors)


# --------------------------------------------------------------------------- numpy
def sym3_cofactors(a):
    """Cofactors, determinant and non-singularity of symmetric 3x3 matrices.

    Parameters
    ----------
    a : sequence of six (n,) arrays, or (6, n) array
        The unique entries (xx, xy, xz, yy, yz, zz) per pixel.

    Returns
    -------
    cof : tuple of six (n,) arrays
        ``(c00, c01, c02, c11, c12, c22)``; ``cof / det`` is the inverse.
    det : (n,) array
    ok : (n,) bool
        ``|det| > RCOND * trace^3``.
    """
    c00, c01, c02, c11, c12, c22, det, ok = _cofactors(*a)
    return (c00, c01, c02, c11, c12, c22), det, ok


def sym3_solve(a, r):
    """Solve ``A x = r`` for every pixel (adjugate / determinant).

    Parameters
    ----------
    a : (6, n) float32
        Unique entries of A per pixel.
    r : (3, n) float32
        Right-hand sides.

    Returns
    -------
    x : (n, 3) float32
        The solution; 0 where singular (the caller fills those pixels).
    ok : (n,) bool
        Non-singular pixels.
    cof : tuple of six (n,) arrays
        The cofactors (``cof * inv_det`` are the inverse's entries).
    inv_det : (n,) float32
        1 / det, 0 where singular.
    """
    cof, det, ok = sym3_cofactors(a)
    c00, c01, c02, c11, c12, c22 = cof
    inv_det = np.divide(np.float32(1), det, out=np.zeros_like(det), where=ok)
    r0, r1, r2 = r
    x = np.empty((r.shape[1], 3), dtype=np.float32)
    x[:, 0] = (c00 * r0 + c01 * r1 + c02 * r2) * inv_det
    x[:, 1] = (c01 * r0 + c11 * r1 + c12 * r2) * inv_det
    x[:, 2] = (c02 * r0 + c12 * r1 + c22 * r2) * inv_det
    return x, ok, cof, inv_det


# --------------------------------------------------------------------------- numba
@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def solve_sym3(a00, a01, a02, a11, a12, a22, r0, r1, r2, out):
    """One pixel: write the float32 solution of ``A x = r`` into ``out`` (3,) and return
    True, or return False (``out`` untouched) where A is singular."""
    c00, c01, c02, c11, c12, c22, det, ok = _cofactors_1(a00, a01, a02, a11, a12, a22)
    if not ok:
        return False
    inv = 1.0 / det
    out[0] = np.float32((c00 * r0 + c01 * r1 + c02 * r2) * inv)
    out[1] = np.float32((c01 * r0 + c11 * r1 + c12 * r2) * inv)
    out[2] = np.float32((c02 * r0 + c12 * r1 + c22 * r2) * inv)
    return True


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def inv_sym3(a00, a01, a02, a11, a12, a22, rcond=RCOND):
    """One pixel: the inverse of A as its 6 unique entries and ``ok`` (zeros where
    singular). ``rcond`` other than :data:`RCOND`: see :data:`HELDOUT_RCOND`."""
    c00, c01, c02, c11, c12, c22, det, ok = _cofactors_1(a00, a01, a02, a11, a12, a22, rcond)
    inv = 1.0 / det if ok else 0.0
    return c00 * inv, c01 * inv, c02 * inv, c11 * inv, c12 * inv, c22 * inv, ok
