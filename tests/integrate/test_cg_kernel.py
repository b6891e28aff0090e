"""The compiled CG passes equal the numpy formulation they replace, bit for bit."""
import numpy as np

from psbench.integrate import _cg_kernel as cg


def _numpy_laplacian(z, wx, wy):
    bx = (z[:, 1:] - z[:, :-1]) * wx
    by = (z[1:, :] - z[:-1, :]) * wy
    out = np.empty_like(z)
    out[:, :-1] = -bx
    out[:, -1] = 0.0
    out[:, 1:] += bx
    out[:-1, :] -= by
    out[1:, :] += by
    return out


def test_laplacian_step_direction_match_numpy_bit_for_bit():
    rng = np.random.default_rng(3)
    for H, W in ((1, 1), (1, 5), (7, 1), (37, 53)):
        mask = rng.random((H, W)) < 0.8
        wx = (mask[:, 1:] & mask[:, :-1]).astype(np.float64)
        wy = (mask[1:, :] & mask[:-1, :]).astype(np.float64)
        z, d, r, y = (rng.normal(size=(H, W)) * 10 ** rng.uniform(-3, 3) for _ in range(4))
        out = np.empty_like(z)
        assert cg.laplacian(z, wx, wy, out) is out
        assert np.array_equal(out, _numpy_laplacian(z, wx, wy))

        a, beta = 0.37, 1.9
        z1, r1, Ad1 = z.copy(), r.copy(), out.copy()
        cg.step(z1, r1, d, Ad1, a)
        assert np.array_equal(z1, z + a * d)
        assert np.array_equal(Ad1, out * a)
        assert np.array_equal(r1, r - out * a)
        d1 = d.copy()
        cg.direction(d1, y, beta)
        assert np.array_equal(d1, d * beta + y)
