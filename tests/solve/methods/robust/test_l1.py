"""l1: least absolute deviations by IRLS."""
from __future__ import annotations

import pytest

from psbench import PsbenchError
from psbench.solve.methods.robust.l1 import L1Options

from _acceptance import errors
from _robust_scenes import fit, lambert_scene, ne, problem


def test_sparse_corruptions_acceptance():
    for l2, e in errors(lambda p: fit("l1", p)):
        assert l2 > 3.0 and e < 0.5, (l2, e)


def test_interpolates_the_inliers():
    """With two gross outliers among 16 observations the L1 fit passes through the
    inliers, and its weights and inlier flags single the outliers out."""
    surf, lay, images = lambert_scene(16)
    bad = images.copy()
    bad[2] *= 3.0
    bad[9] = 0.0
    f = fit("l1", problem(bad, lay, object_mask=surf.object_mask))
    assert ne(f.b, surf.normals, surf.object_mask) < 0.01
    assert not f.valid[[2, 9]].any() and f.valid[[i for i in range(16) if i not in (2, 9)]].all()
    assert (f.weights[[2, 9]] < 0.01).all()


@pytest.mark.parametrize("kw", [{"eps": 0}, {"eps": 0.5}, {"inlier_k": 0}])
def test_option_ranges(kw):
    with pytest.raises(PsbenchError, match=next(iter(kw))):
        L1Options(**kw)
