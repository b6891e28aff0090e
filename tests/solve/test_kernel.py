import numpy as np

import psbench as ps
from psbench.solve.kernel import complete_three, lambert, ls, residuals, split, wls


def _scene(k_spec="30x8+60x8", size=32, seed=0):
    rng = np.random.default_rng(seed)
    lay = ps.layout(k_spec)
    n = rng.normal(size=(size, size, 3))
    n[..., 2] = np.abs(n[..., 2]) + 1.0
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    rho = rng.uniform(0.2, 1.0, size=(size, size))
    b = (n * rho[..., None]).astype(np.float32)
    return lay, n, rho, b, lambert(b, lay.S)


def test_ls_and_wls_recover_exact_lambert():
    lay, n, rho, b, I = _scene()
    for est in (ls(I, lay.S), wls(I, lay.S, np.ones_like(I))):
        nn, a = split(est)
        np.testing.assert_allclose(nn, n, atol=1e-5)
        np.testing.assert_allclose(a, rho, atol=1e-5)


def test_wls_ignores_zero_weight_outliers():
    lay, n, rho, b, I = _scene()
    I = I.copy()
    I[0] += 5.0  # gross outlier in image 0
    w = np.ones_like(I)
    w[0] = 0
    nn, _ = split(wls(I, lay.S, w))
    np.testing.assert_allclose(nn, n, atol=1e-5)
    nn_ls, _ = split(ls(I, lay.S))
    assert np.abs(nn_ls - n).max() > 0.1  # the outlier does hurt plain LS


def test_light_power_is_honoured():
    lay = ps.layout("45x8", power=np.linspace(0.5, 2.0, 8))
    _, n, rho, b, _ = _scene("45x8")
    I = lambert(b, lay.S)
    nn, a = split(ls(I, lay.S))
    np.testing.assert_allclose(nn, n, atol=1e-5)
    np.testing.assert_allclose(a, rho, atol=1e-5)


def test_zero_albedo_gives_up_normal():
    b = np.zeros((4, 4, 3), np.float32)
    n, a = split(b)
    assert (n[..., 2] == 1).all() and (a == 0).all()


def test_complete_three_adds_least_residual():
    k = 6
    valid = np.zeros((k, 1, 2), bool)
    valid[[0, 1], 0, 0] = True          # pixel 0: two valid
    valid[[0, 1, 2, 3], 0, 1] = True    # pixel 1: four valid (untouched)
    res = np.array([9, 9, 5, 0.1, 3, 7], np.float32)[:, None, None] * np.ones((k, 1, 2), np.float32)
    out = complete_three(valid, res)
    assert out[:, 0, 0].tolist() == [True, True, False, True, False, False]
    assert (out[:, 0, 1] == valid[:, 0, 1]).all()


def test_residuals_zero_for_exact_model():
    lay, n, rho, b, I = _scene()
    assert np.abs(residuals(I, b, lay.S)).max() < 1e-5
