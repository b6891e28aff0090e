"""sbl: sparse Bayesian learning of the outliers."""
from __future__ import annotations

import numpy as np
import pytest

from psbench import PsbenchError
from psbench.solve.methods.robust.sbl import SBLOptions

from _acceptance import corrupted, errors
from _robust_scenes import fit, problem


def test_sparse_corruptions_acceptance():
    for l2, e in errors(lambda p: fit("sbl", p)):
        assert l2 > 3.0 and e < 0.5, (l2, e)


def test_weights_and_inliers_find_the_planted_outliers():
    surf, lay, bad, hit = corrupted(1)
    f = fit("sbl", problem(bad, lay, object_mask=surf.object_mask))
    assert (f.weights > 0).all() and f.weights.max() <= 1.0
    # nearly every planted outlier is flagged (measured 0.999); some inliers of the
    # most corrupted pixels are flagged too (precision measured 0.85)
    flagged = ~f.valid
    assert (flagged & hit).sum() / hit.sum() > 0.99
    assert (flagged & hit).sum() / flagged.sum() > 0.8
    assert np.median(f.weights[hit]) < 1e-2 < np.median(f.weights[~hit])
    assert f.info["lambda"] > 0


@pytest.mark.parametrize("sigma", [0, -0.1, 1.5, None])
def test_sigma_range(sigma):
    with pytest.raises(PsbenchError, match="sigma"):
        SBLOptions(sigma=sigma)
