"""The one symmetric 3x3 solve: numpy and compiled twins agree, singular matrices are
refused by the same rule, and the kernels that use it give the solution of A x = r."""
import numpy as np
import pytest
from numba import njit

from psbench.solve._sym3 import RCOND, inv_sym3, solve_sym3, sym3_cofactors, sym3_solve

_IU = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))


@njit(cache=False)
def _solve_all(a, r, out, ok):
    for p in range(a.shape[1]):
        ok[p] = solve_sym3(a[0, p], a[1, p], a[2, p], a[3, p], a[4, p], a[5, p],
                           r[0, p], r[1, p], r[2, p], out[p])


@njit(cache=False)
def _inv_all(a, out, ok):
    for p in range(a.shape[1]):
        i00, i01, i02, i11, i12, i22, ok[p] = inv_sym3(a[0, p], a[1, p], a[2, p], a[3, p],
                                                        a[4, p], a[5, p])
        out[p, 0], out[p, 1], out[p, 2] = i00, i01, i02
        out[p, 3], out[p, 4], out[p, 5] = i11, i12, i22


def _matrices(n, seed=0):
    """Normal matrices sum_i w_i s_i s_i^T of random lights: regular ones, rank-2 ones
    (all lights in a plane), all-zero ones and ones scaled by 1e-20 / 1e20."""
    rng = np.random.default_rng(seed)
    S = rng.normal(size=(n, 8, 3))
    S[n // 4:n // 2, :, 2] = 0.0                       # rank 2
    w = rng.uniform(0, 1, size=(n, 8))
    w[n // 2:n // 2 + 10] = 0.0                        # nothing used
    w[-20:-10] *= 1e-20
    w[-10:] *= 1e20
    A = np.einsum("pi,pij,pik->pjk", w, S, S)
    return A, rng.normal(size=(n, 3))


def test_numpy_and_compiled_agree_and_solve():
    A, r = _matrices(400)
    a = A[:, _IU[0], _IU[1]].T.copy()
    x, ok, cof, inv_det = sym3_solve(a, r.T.copy())
    out, ok_c = np.zeros((400, 3), np.float32), np.zeros(400, bool)
    _solve_all(a, r.T.copy(), out, ok_c)
    np.testing.assert_array_equal(ok, ok_c)
    assert ok.sum() > 200 and (~ok).sum() >= 110     # rank-2 and empty ones refused
    assert not ok[100:200].any() and not ok[200:210].any()
    assert ok[-20:].all()                            # the rule does not depend on scale
    ref = np.linalg.solve(A[ok], r[ok][..., None])[..., 0]
    np.testing.assert_allclose(x[ok], ref, rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(out[ok], ref, rtol=1e-6, atol=1e-12)
    assert (x[~ok] == 0).all() and (inv_det[~ok] == 0).all()
    inv, ok_i = np.zeros((400, 6)), np.zeros(400, bool)
    _inv_all(a, inv, ok_i)
    np.testing.assert_array_equal(ok_i, ok)
    np.testing.assert_allclose(inv[ok], np.stack(cof, 1)[ok] * inv_det[ok, None], rtol=1e-9)
    assert (inv[~ok] == 0).all()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_rule(dtype):
    """Singular exactly when |det| <= RCOND trace^3, in both precisions."""
    eps = np.array([1e-1, 1e-3, 1e-5, 2e-6, 1e-7], dtype)
    a = np.stack([np.ones_like(eps), 0 * eps, 0 * eps, np.ones_like(eps), 0 * eps, eps])
    _, det, ok = sym3_cofactors(a)
    tr = 2 + eps
    np.testing.assert_array_equal(ok, np.abs(det) > RCOND * tr * tr * tr)
    assert ok.tolist() == [True, True, True, False, False]
