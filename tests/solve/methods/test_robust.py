"""robust: noise-calibrated rank windows followed by concentration steps."""
from __future__ import annotations

import numpy as np
import pytest

from psbench import PsbenchError
from psbench.solve.methods.robust import RobustOptions

from _acceptance import corrupted, errors
from _robust_scenes import fit, lambert_scene, problem, ts_scene


def test_sparse_corruptions():
    for l2, e in errors(lambda p: fit("robust", p)):
        assert l2 > 3.0 and e < 0.5, (l2, e)


def test_noise_level_is_estimated():
    for noise in (0.02, 0.08):
        surf, lay, images = lambert_scene(32)
        rng = np.random.default_rng(0)
        noisy = images + rng.normal(0, noise, images.shape).astype(np.float32)
        p = problem(noisy, lay, object_mask=surf.mask, scale=1.0)
        f = fit("robust", p)
        assert f.info["sigma"] == pytest.approx(noise, rel=0.3)
        # pure noise: (nearly) every observation is kept
        assert f.valid.mean() > 0.95


def test_drops_from_both_ends():
    """On the Torrance-Sparrow scene with shadows the window stage drops dark and
    bright observations (NE is not checked here: on this noiseless scene with broad
    highlight lobes robust is no better than least squares -- see the benchmark)."""
    surf, lay, images = ts_scene(40)
    f = fit("robust", problem(images, lay, object_mask=surf.mask))
    assert f.info["mean_dropped_dark"] > 0.5 and f.info["mean_dropped_bright"] > 0.1
    assert f.info["converged_fraction"] == 1.0


def test_given_sigma_and_cutoff():
    surf, lay, bad, hit = corrupted(1)
    p = problem(bad, lay, object_mask=surf.mask)
    f = fit("robust", p, sigma=0.01, c=3.0)
    assert f.info["sigma"] == pytest.approx(0.01) and f.info["c"] == 3.0
    assert ((~f.valid) == hit)[:, surf.mask].mean() > 0.97


@pytest.mark.parametrize("kw", [{"c": 0}, {"sigma": 0}, {"sigma": 2}, {"max_drop": 0.5},
                                {"max_drop": -0.1}])
def test_option_ranges(kw):
    with pytest.raises(PsbenchError, match=next(iter(kw))):
        RobustOptions(**kw)
