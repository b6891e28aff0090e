"""robust: per pixel the better (truncated loss) of a trimmed Lambertian fit and a
Lambert + Torrance-Sparrow fit."""
from __future__ import annotations

import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError
from psbench.solve.methods.robust import RobustOptions, ts_predict

from _acceptance import errors
from _robust_scenes import fit, ne, problem, ts_scene


def test_sparse_corruptions():
    """Gross outliers no lobe explains: the trimmed fit wins where they are."""
    for l2, e in errors(lambda p: fit("robust", p)):
        assert l2 > 3.0 and e < 0.5, (l2, e)


def test_models_the_highlight():
    """On a Torrance-Sparrow scene with noise the Torrance-Sparrow fit is chosen almost
    everywhere and beats the trimmed Lambertian fit and least squares."""
    surf, lay, images = ts_scene(40, noise=0.02)
    om = surf.object_mask
    p = problem(images, lay, object_mask=om)
    f = fit("robust", p)
    e = ne(f.b, surf.normals, om)
    e_l = ne(fit("robust", problem(images, lay, object_mask=om), model="lambert").b,
             surf.normals, om)
    assert f.info["ts_fraction"] > 0.8
    assert e < 0.6 * e_l and e < 0.5 * ne(p.start(), surf.normals, om), (e, e_l)
    assert np.isfinite(f.b).all()


def test_lambert_model_is_trim():
    surf, lay, images = ts_scene(24, noise=0.02)
    p = problem(images, lay, object_mask=surf.object_mask)
    a = fit("robust", p, model="lambert")
    b = fit("trim", p)
    np.testing.assert_array_equal(a.b, b.b)
    assert a.info["ts_fraction"] == 0.0


def test_few_images_use_the_trimmed_fit():
    surf, lay, images = ts_scene(16, lights="45x4", noise=0.0)
    f = fit("robust", problem(images, lay, object_mask=surf.object_mask))
    assert f.info["ts_fraction"] == 0.0 and np.isfinite(f.b).all()


def test_prediction_matches_the_renderer():
    """The model the choice is made with is the renderer's Torrance-Sparrow model."""
    surf = ps.make_surface("sombrero2", size=24)
    lay = ps.layout("30x8+60x8")
    sc = ps.render(surf, lay, model="ts", shadows="self", rho_d=0.7, rho_s=0.4, m=3.0)
    om = surf.object_mask
    b = (0.7 * surf.normals[om]).astype(np.float32)
    f = ts_predict(lay.directions, lay.power, b, 0.4, 3.0)
    np.testing.assert_allclose(f, sc.images[:, om].T, atol=2e-5)


@pytest.mark.parametrize("kw", [{"c": 0}, {"c": -1}, {"model": "phong"}])
def test_option_ranges(kw):
    with pytest.raises(PsbenchError, match=next(iter(kw))):
        RobustOptions(**kw)
