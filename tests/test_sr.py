"""SR, the secondary-reflection mask prototype (psbench._sr)."""
import numpy as np
import pytest

import psbench as ps
from psbench._sr import predict, solve_sr, sr_valid, sr_weights
from psbench.surfaces import surface_from_height
from psbench.surfaces.cup import cup


def _mask(s):
    return np.asarray(s.object_mask if hasattr(s, "object_mask") else s.mask)


@pytest.fixture(scope="module")
def lambert_cup():
    """Noiseless Lambert cup with one bounce; the truth rendered at 48 azimuths so that its
    own quadrature error stays well below what SR (24 azimuths) is asked to reach."""
    surf = cup(96)
    lay = ps.layout("30x8+60x8")
    scene = ps.render(surf, lay, model="lambert", bounces=1, bounce_samples=48)
    return surf, lay, scene


def test_sr_recovers_lambert_cup(lambert_cup):
    """Acceptance: SR < 0.5 deg where plain least squares is off by > 2 deg."""
    surf, lay, scene = lambert_cup
    m = _mask(surf)
    none = ps.solve(scene.images, lay, object_mask=m)
    ne_none = ps.normal_error(none.normals, surf.normals, m)
    fit = solve_sr(scene.images, lay, object_mask=m, truth_normals=surf.normals)
    ne_sr = ps.normal_error(fit.normals, surf.normals, m)
    assert ne_none > 2.0
    assert ne_sr < 0.5
    assert fit.converged and fit.iterations <= 10
    # the shadowed observations (pure secondary light) are the ones SR masks
    shadow = scene.self_shadow | scene.cast_shadow
    assert (~fit.valid[shadow]).mean() > 0.9
    assert fit.valid[~shadow & m[None]].mean() > 0.9


def test_sr_weighted_form(lambert_cup):
    surf, lay, scene = lambert_cup
    m = _mask(surf)
    fit = solve_sr(scene.images, lay, object_mask=m, weighted=True)
    assert fit.weights is not None and fit.weights.dtype == np.float32
    assert ps.normal_error(fit.normals, surf.normals, m) < 0.5


def test_mask_alone_cannot_remove_lambertian_interreflection(lambert_cup):
    """Without the subtraction SR masks the shadowed observations only: the lit ones agree
    on a pseudo-normal (rho n + kappa z in a cup), so the error stays large."""
    surf, lay, scene = lambert_cup
    m = _mask(surf)
    fit = solve_sr(scene.images, lay, object_mask=m, correct=False)
    assert ps.normal_error(fit.normals, surf.normals, m) > 2.0


def test_prediction_on_true_geometry_matches_rendered_secondary():
    surf = cup(64)
    m = _mask(surf)
    lay = ps.layout("30x4+60x4")
    scene = ps.render(surf, lay, model="lambert", bounces=1, bounce_samples=32)
    b = surf.normals * m[..., None]
    pred = predict(b, lay, object_mask=m, images=scene.images, height=surf.height, samples=32)
    true = scene.secondary_fraction * scene.images
    inner = m & (np.hypot(*np.meshgrid(np.arange(64) - 31.5, np.arange(64) - 31.5)) < 26)
    rel = np.abs(pred.secondary - true)[:, inner].mean() / true[:, inner].mean()
    assert rel < 0.05
    assert pred.fraction.shape == scene.images.shape
    assert ((pred.fraction >= 0) & (pred.fraction <= 1)).all()
    v, w = sr_valid(pred), sr_weights(pred)
    assert v.dtype == bool and (w[~v] == 0).all() and (w[v] > 0).all()


def test_plane_predicts_no_secondary_light():
    x = np.arange(40)[None, :] * np.ones((40, 1))
    surf = surface_from_height(0.3 * x)
    lay = ps.layout("45x8")
    scene = ps.render(surf, lay, model="lambert")
    res = ps.solve(scene.images, lay)
    pred = predict(res.b, lay, images=scene.images)
    assert np.abs(pred.secondary).max() < 1e-6
    fit = solve_sr(scene.images, lay, max_iter=2)
    np.testing.assert_allclose(fit.normals, res.normals, atol=1e-4)


def test_sr_bad_input():
    imgs = np.ones((4, 16, 16), np.float32)
    with pytest.raises(ps.PsbenchError, match="t_sr"):
        solve_sr(imgs, ps.layout("45x4"), t_sr=0)
    with pytest.raises(ps.PsbenchError, match="lights"):
        solve_sr(imgs, ps.layout("45x8"))
    with pytest.raises(ps.PsbenchError, match="source"):
        predict(np.ones((16, 16, 3), np.float32), ps.layout("45x4"), source="rays")
