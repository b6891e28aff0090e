"""The compiled kernels of trim and the M-estimators against test-local numpy references,
on short rows (rank counting) and long ones (bisection), with masks and ties; results
independent of the thread count."""
import numba
import numpy as np
import pytest

from psbench.solve.methods.robust._kernel import WEIGHT_FUNCTIONS, SHORT, irls_m, trim_rows


def _lights(k, rng):
    d = rng.normal(size=(k, 3))
    d[:, 2] = np.abs(d[:, 2]) + 0.5
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def _inputs(k, n, masked, ties, seed=0):
    rng = np.random.default_rng(seed)
    S = _lights(k, rng)
    b = rng.normal(size=(n, 3)) * 0.2 + np.array([0, 0, 1.0])
    I = np.maximum(b @ S.T, 0) + 0.02 * rng.normal(size=(n, k))
    if ties:  # runs of equal values (zeros in shadow, quantised levels)
        I = np.round(I * 8) / 8
    I = np.ascontiguousarray(I.T, dtype=np.float32)            # (k, n)
    V = rng.random((k, n)) > 0.25 if masked else np.ones((1, 1), dtype=bool)
    O = np.stack([S[:, 0] * S[:, 0], S[:, 0] * S[:, 1], S[:, 0] * S[:, 2],
                  S[:, 1] * S[:, 1], S[:, 1] * S[:, 2], S[:, 2] * S[:, 2]]).astype(np.float32)
    return I, V, S, O, np.ascontiguousarray(S.T, dtype=np.float32)


def _ref_keep(I, V, dark, bright):
    """The rank trimming by sorting (numpy): above the nd-th smallest valid value and
    below the (m - nb + 1)-th; the exact rank window when ties leave fewer than 3."""
    x = np.where(V, I, np.float32(np.inf))
    m = V.sum(axis=0)
    red = np.maximum(m - 3, 0)
    nd = np.floor(dark * red + 0.5).astype(int)
    nb = np.floor(bright * red + 0.5).astype(int)
    s = np.sort(x, axis=0)
    cols = np.arange(I.shape[1])
    lo = np.where(nd > 0, s[np.maximum(nd - 1, 0), cols], -np.inf)
    hi = np.where(nb > 0, s[np.minimum(m - nb, I.shape[0] - 1), cols], np.inf)
    keep = V & (I > lo) & (I < hi)
    short = keep.sum(axis=0) < np.minimum(3, m)
    rank = np.argsort(np.argsort(x, axis=0, kind="stable"), axis=0, kind="stable")
    win = V & (rank >= nd) & (rank < m - nb)
    keep[:, short] = win[:, short]
    return keep


@pytest.mark.parametrize("k", [16, SHORT + 16])
@pytest.mark.parametrize("masked", [False, True])
@pytest.mark.parametrize("ties", [False, True])
def test_trim_matches_reference(k, masked, ties):
    n = 700
    I, V, S, O, St = _inputs(k, n, masked, ties)
    Vfull = V if masked else np.ones(I.shape, dtype=bool)
    b = np.empty((n, 3), dtype=np.float32)
    keep = np.empty(I.shape, dtype=bool)
    P = np.linalg.pinv(S).astype(np.float32)
    trim_rows(I, V, not masked, O, St, P, 0.25, 0.25, 0, False, b, keep)
    ref = _ref_keep(I, Vfull, 0.25, 0.25)
    assert np.array_equal(keep, ref)
    for p in range(0, n, 37):  # least squares on the kept observations
        sel = keep[:, p]
        want = np.linalg.lstsq(S[sel], I[sel, p].astype(np.float64), rcond=None)[0]
        np.testing.assert_allclose(b[p], want, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("k", [16, SHORT + 16])
def test_concentration_step_keeps_smallest_residuals(k):
    n = 600
    I, V, S, O, St = _inputs(k, n, True, False, seed=1)
    P = np.linalg.pinv(S).astype(np.float32)
    b0 = np.empty((n, 3), dtype=np.float32)
    keep0 = np.empty(I.shape, dtype=bool)
    trim_rows(I, V, False, O, St, P, 0.25, 0.25, 0, False, b0, keep0)
    b1 = np.empty((n, 3), dtype=np.float32)
    keep1 = np.empty(I.shape, dtype=bool)
    trim_rows(I, V, False, O, St, P, 0.25, 0.25, 1, True, b1, keep1)
    r = np.abs(I - (b0 @ St).T)
    r[~V] = np.inf
    h = V.sum(axis=0) // 2 + 1
    t = np.sort(r, axis=0)[h - 1, np.arange(n)]
    assert np.array_equal(keep1, r <= t)


def _ref_irls(I, V, S, b0, c, kind, floor, tol, n_iter):
    """Test-local IRLS M-estimate of one pixel (float64)."""
    b = b0.astype(np.float64)
    r = I - S @ b
    sigma = max(1.4826 * np.median(np.abs(r[V])), floor)
    for it in range(1, n_iter + 1):
        u = (I - S @ b) / (c * sigma)
        w = {"huber": 1 / np.maximum(np.abs(u), 1), "cauchy": 1 / (1 + u * u),
             "tukey": np.maximum(1 - u * u, 0) ** 2}[kind] * V
        bn = np.linalg.solve((S * w[:, None]).T @ S, (S * w[:, None]).T @ I)
        done = np.linalg.norm(bn - b) <= tol * np.linalg.norm(bn)
        b = bn
        if done:
            break
    return b, it, sigma


@pytest.mark.parametrize("kind", sorted(WEIGHT_FUNCTIONS))
@pytest.mark.parametrize("k", [16, SHORT + 16])
def test_irls_matches_reference(kind, k):
    n = 300
    I, V, S, O, St = _inputs(k, n, True, False, seed=2)
    rng = np.random.default_rng(3)
    I = I * np.where(rng.random(I.shape) < 0.15, 3.0, 1.0).astype(np.float32)  # outliers
    b0 = np.ascontiguousarray(np.linalg.lstsq(S, I, rcond=None)[0].T, dtype=np.float32)
    out = (np.empty((n, 3), np.float32), np.empty(I.shape, np.float32),
           np.empty(I.shape, bool), np.empty(n, np.int32), np.empty(n, bool),
           np.empty(n, np.float32))
    irls_m(I, V, False, O, St, b0, np.float32(2.0), WEIGHT_FUNCTIONS[kind], False, np.float32(1e-5),
           np.float32(1e-6), np.float32(1e-6), 200, *out)
    b, w, inl, its, conv, sigma = out
    assert conv.all()
    for p in range(0, n, 23):
        want, _, s_want = _ref_irls(I[:, p].astype(np.float64), V[:, p], S, b0[p], 2.0, kind,
                                    1e-5, 1e-6, 200)
        np.testing.assert_allclose(sigma[p], s_want, rtol=1e-5)
        np.testing.assert_allclose(b[p], want, rtol=2e-4, atol=2e-4)
        assert not w[~V[:, p], p].any()


def test_kernels_do_not_depend_on_thread_count():
    k, n = 16, 3000
    I, V, S, O, St = _inputs(k, n, True, True, seed=4)
    P = np.linalg.pinv(S).astype(np.float32)
    res = []
    saved = numba.get_num_threads()
    try:
        for t in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(t)
            b = np.empty((n, 3), np.float32)
            keep = np.empty(I.shape, bool)
            trim_rows(I, V, False, O, St, P, 0.25, 0.25, 1, False, b, keep)
            out = (np.empty((n, 3), np.float32), np.empty(I.shape, np.float32),
                   np.empty(I.shape, bool), np.empty(n, np.int32), np.empty(n, bool),
                   np.empty(n, np.float32))
            irls_m(I, V, False, O, St, b, np.float32(2.385), WEIGHT_FUNCTIONS["cauchy"], True,
                   np.float32(1e-5), np.float32(1e-6), np.float32(1e-3), 50, *out)
            res.append((b, keep) + out)
    finally:
        numba.set_num_threads(saved)
    for a, b in zip(res[0], res[-1]):
        assert np.array_equal(a, b)
