"""rpca: low-rank + sparse decomposition by inexact ALM."""
from __future__ import annotations

import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError
from psbench.solve.methods.robust.rpca import RPCAOptions, rpca

from _acceptance import errors
from _robust_scenes import fit, lambert_scene, problem, ts_scene


def test_sparse_corruptions_acceptance():
    for l2, e in errors(lambda p: fit("rpca", p)):
        assert l2 > 3.0 and e < 0.5, (l2, e)


def test_needs_four_images_before_any_work():
    surf, lay, images = lambert_scene(16, lights="45x3")
    p = problem(images, lay)
    p._start = lambda: pytest.fail("rpca started working on a 3-image stack")
    with pytest.raises(PsbenchError, match="at least 4 images, got 3"):
        rpca(p, RPCAOptions())
    assert RPCAOptions.min_images == 4


def test_reports_rank_and_sparse_inliers():
    surf, lay, images = ts_scene(32)
    f = fit("rpca", problem(images, lay, object_mask=surf.object_mask))
    assert f.info["rank"] == 3 and f.converged is True and isinstance(f.iterations, int)
    assert 0.5 < f.valid[:, surf.object_mask].mean() < 1.0   # shadows / highlights flagged


def test_falls_back_and_warns_when_too_few_observations():
    surf, lay, images = ts_scene(40, noise=0.02)
    valid = ps.solve(images, lay, mask="Th", object_mask=surf.object_mask).valid  # ~75 % dropped
    p = problem(images, lay, valid=valid, object_mask=surf.object_mask)
    with pytest.warns(RuntimeWarning) as rec:
        f = fit("rpca", p, quiet=False)
    assert any("falling back to masked least squares" in str(w.message) for w in rec)
    assert f.info["fallback"] == "ls" and f.converged is False
    np.testing.assert_allclose(f.b, p.start(), atol=1e-6)


@pytest.mark.parametrize("kw", [{"rank": 0}, {"rank": 1.5}, {"lam": 0}, {"rho": 1.0},
                                {"tol": 1.0}, {"inlier_k": -1}])
def test_option_ranges(kw):
    with pytest.raises(PsbenchError, match=next(iter(kw))):
        RPCAOptions(**kw)


@pytest.mark.realdata
def test_falls_back_when_completion_fails_on_real_data(diligent):
    """The literal Th keeps the dimmer half of every DiLiGenT image: a systematic
    missing pattern that completion cannot fill; rpca notices and says so."""
    from psbench.harness.run import select_lights
    from psbench.io import read_dataset

    ds = read_dataset(diligent / "cat")
    images, lights = select_lights(ds.images, ds.lights, "30x8+60x8")
    valid = ps.solve(images, lights, mask="Th", object_mask=ds.object_mask).valid
    p = problem(images, lights, valid=valid, object_mask=ds.object_mask)
    f = fit("rpca", p)
    assert f.info["fallback"] == "ls"
    assert f.info["median_residual"] > f.info["median_residual_ls"]
    np.testing.assert_allclose(f.b[ds.object_mask], p.start()[ds.object_mask], atol=1e-6)
