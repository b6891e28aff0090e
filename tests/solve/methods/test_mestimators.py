"""huber, cauchy, tukey: M-estimators by IRLS with a per-pixel MAD scale."""
from __future__ import annotations

import numpy as np
import pytest

from psbench import PsbenchError
from psbench.solve.methods import cauchy, huber, tukey

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


def test_weight_functions():
    u = np.array([0.0, 0.5, 0.99, 1.0, 2.0, 10.0], dtype=np.float32)
    h = huber._weight(u.copy())
    np.testing.assert_allclose(h, [1, 1, 1, 1, 0.5, 0.1], rtol=1e-6)
    c = cauchy._weight(u.copy())
    np.testing.assert_allclose(c, 1 / (1 + u * u), rtol=1e-6)
    t = tukey._weight(u.copy())
    np.testing.assert_allclose(t, np.where(u < 1, (1 - u * u) ** 2, 0), atol=1e-6)
    assert (np.diff(c) < 0).all() and t[0] == 1 and (t[3:] == 0).all()


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
