"""huber, cauchy, tukey: M-estimators by IRLS with a per-pixel MAD scale."""
from __future__ import annotations

import numpy as np
import pytest

from psbench import PsbenchError
from psbench.solve.methods.robust import cauchy, huber, tukey

from _acceptance import errors
from _robust_scenes import fit, problem, ts_scene


@pytest.mark.parametrize("name", ["cauchy", "tukey"])
def test_sparse_corruptions_acceptance(name):
    for l2, e in errors(lambda p: fit(name, p)):
        assert l2 > 3.0 and e < 0.5, (l2, e)


def test_huber_on_sparse_corruptions():
    """Huber bounds but does not remove outliers: better than least squares by far,
    not as exact as the redescending estimators."""
    for l2, e in errors(lambda p: fit("huber", p)):
        assert e < 0.1 * l2


@pytest.mark.parametrize("kind", ["huber", "cauchy", "tukey"])
def test_weight_functions(kind):
    """The first IRLS weights of the compiled loop are w(u) of u = r / (c sigma),
    sigma = 1.4826 median |r| of the start."""
    from psbench.solve.methods.robust._kernel import WEIGHT_FUNCTIONS, irls_m

    rng = np.random.default_rng(0)
    k = 16
    S = rng.normal(size=(k, 3))
    S[:, 2] = np.abs(S[:, 2]) + 1
    b0 = np.array([[0.1, -0.2, 1.0]], dtype=np.float32)
    r = np.linspace(-3, 3, k).astype(np.float32)
    I = np.ascontiguousarray((S @ b0[0]).astype(np.float32) + r)[:, None]
    O = np.stack([S[:, 0] * S[:, 0], S[:, 0] * S[:, 1], S[:, 0] * S[:, 2], S[:, 1] * S[:, 1],
                  S[:, 1] * S[:, 2], S[:, 2] * S[:, 2]]).astype(np.float32)
    St = np.ascontiguousarray(S.T, dtype=np.float32)
    out = (np.empty((1, 3), np.float32), np.empty((k, 1), np.float32), np.empty((k, 1), bool),
           np.empty(1, np.int32), np.empty(1, bool), np.empty(1, np.float32))
    c = 1.5
    irls_m(I, np.ones((1, 1), bool), True, O, St, b0, np.float32(c), WEIGHT_FUNCTIONS[kind], False,
           np.float32(1e-6), np.float32(1e-6), np.float32(1e-3), 1, *out)
    w, sigma = out[1][:, 0], out[5][0]
    r_now = I[:, 0] - (S @ b0[0]).astype(np.float32)
    assert sigma == pytest.approx(1.4826 * np.median(np.abs(r_now)), rel=1e-5)
    u = r_now / (c * sigma)
    want = {"huber": np.minimum(1, 1 / np.abs(u)), "cauchy": 1 / (1 + u * u),
            "tukey": np.maximum(1 - u * u, 0) ** 2}[kind]
    np.testing.assert_allclose(w, want, rtol=1e-5, atol=1e-6)
    assert w.max() <= 1 and (kind != "tukey" or (w[np.abs(u) >= 1] == 0).all())


@pytest.mark.parametrize("start", ["lts", "trim", "ls"])
def test_starts_and_inliers(start):
    surf, lay, images = ts_scene(32, noise=0.02)
    f = fit("tukey", problem(images, lay, object_mask=surf.object_mask), start=start)
    assert f.info["start"] == start and f.info["c"] == pytest.approx(4.685)
    # Tukey: weight > 0 exactly for the inliers |r| < c sigma
    on = surf.object_mask[None]
    assert ((f.weights > 0) == f.valid)[np.broadcast_to(on, f.valid.shape)].mean() > 0.999


@pytest.mark.parametrize("mod", [huber, cauchy, tukey])
def test_option_ranges(mod):
    opts = [v for k, v in vars(mod).items() if k.endswith("Options")][0]
    with pytest.raises(PsbenchError, match="c must"):
        opts(c=0)
    with pytest.raises(PsbenchError, match="start='median' is not known; valid choices: lts"):
        opts(start="median")
