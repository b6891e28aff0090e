"""SR, the secondary-reflection mask (psbench._sr, psbench.solve.masks.sr) through ps.solve."""
import numpy as np
import pytest

import psbench as ps
from psbench.solve.masks._sr import predict, sr_valid
from psbench.surfaces import surface_from_height
from psbench.surfaces.cup import cup


@pytest.fixture(scope="module")
def lambert_cup():
    """Noiseless Lambert cup with one bounce; the truth rendered at 48 azimuths so that its
    own quadrature error stays well below what SR (24 azimuths) is asked to reach."""
    surf = cup(96)
    lay = ps.layout("30x8+60x8")
    scene = ps.render(surf, lay, model="lambert", bounces=1, bounce_samples=48)
    return surf, lay, scene


def _ne(res, surf):
    return ps.normal_error(res.normals, surf.normals, object_mask=surf.object_mask)


def test_sr_recovers_lambert_cup(lambert_cup):
    """Acceptance: SR < 0.5 deg where plain least squares is off by > 2 deg."""
    surf, lay, scene = lambert_cup
    m = surf.object_mask
    none = ps.solve(scene.images, lay, object_mask=m)
    res = ps.solve(scene.images, lay, mask="SR", object_mask=m)
    assert _ne(none, surf) > 2.0
    assert _ne(res, surf) < 0.5
    assert res.mask == "SR" and 1 <= res.iterations <= 10
    assert res.info["correction"].shape == scene.images.shape
    assert len(res.info["change"]) == res.iterations
    # the shadowed observations (pure secondary light) are the ones SR masks
    shadow = scene.self_shadow | scene.cast_shadow
    assert (~res.valid[shadow]).mean() > 0.9
    assert res.valid[~shadow & m[None]].mean() > 0.9


def test_sr_weighted_form(lambert_cup):
    surf, lay, scene = lambert_cup
    res = ps.solve(scene.images, lay, mask="SR", object_mask=surf.object_mask, weighted=True)
    assert res.weights is not None and res.weights.dtype == np.float32
    assert _ne(res, surf) < 0.5


def test_sr_in_a_combination(lambert_cup):
    """Th-Hi-Re-Sh-SR: the other masks judge the corrected images. On raw images
    interreflection lifts the shadowed observations above Th, and Sh's heights
    come from the biased normals: Th-Hi-Re-Sh alone is far off."""
    surf, lay, scene = lambert_cup
    m = surf.object_mask
    plain = ps.solve(scene.images, lay, mask="Th-Hi-Re-Sh", object_mask=m)
    res = ps.solve(scene.images, lay, mask="Th-Hi-Re-Sh-SR", object_mask=m)
    assert res.mask == "Th-Hi-Re-Sh-SR"
    assert _ne(plain, surf) > 5.0
    assert _ne(res, surf) < 2.0


def test_mask_alone_cannot_remove_lambertian_interreflection(lambert_cup):
    """Without the subtraction SR masks the shadowed observations only: the lit ones agree
    on a pseudo-normal (rho n + kappa z in a cup), so the error stays large."""
    surf, lay, scene = lambert_cup
    res = ps.solve(scene.images, lay, mask="SR", object_mask=surf.object_mask,
                   sr_correct=False)
    assert "correction" not in res.info
    assert _ne(res, surf) > 2.0


def test_prediction_on_true_geometry_matches_rendered_secondary():
    surf = cup(64)
    m = surf.object_mask
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
    v = sr_valid(pred)
    assert v.dtype == bool and np.array_equal(v, pred.fraction <= 0.5)


def test_plane_predicts_no_secondary_light():
    x = np.arange(40)[None, :] * np.ones((40, 1))
    surf = surface_from_height(0.3 * x)
    lay = ps.layout("45x8")
    scene = ps.render(surf, lay, model="lambert")
    res = ps.solve(scene.images, lay)
    pred = predict(res.b, lay, images=scene.images)
    assert np.abs(pred.secondary).max() < 1e-6
    sr = ps.solve(scene.images, lay, mask="SR", max_iter=2)
    np.testing.assert_allclose(sr.normals, res.normals, atol=1e-4)
    assert sr.valid.all()


def test_masks_without_correction_are_untouched():
    """The correction path is SR's alone: a mask expression without SR returns no
    correction record."""
    surf = cup(48)
    lay = ps.layout("30x8")
    scene = ps.render(surf, lay, model="ts", bounces=1, bounce_samples=8)
    res = ps.solve(scene.images, lay, mask="Th-Hi-Re-Sh", object_mask=surf.object_mask)
    assert "correction" not in res.info and "change" not in res.info


def test_sr_bad_input():
    imgs = np.ones((4, 16, 16), np.float32)
    lay = ps.layout("45x4")
    with pytest.raises(ps.PsbenchError, match="t_sr"):
        ps.solve(imgs, lay, mask="SR", thresholds={"t_sr": 2.0})
    with pytest.raises(ps.PsbenchError, match="sr_samples"):
        ps.solve(imgs, lay, mask="SR", sr_samples=2)
    with pytest.raises(ps.PsbenchError, match="sr_source"):
        ps.solve(imgs, lay, mask="SR", sr_source="rays")
    with pytest.raises(ps.PsbenchError, match="sr_bounces"):
        ps.solve(imgs, lay, mask="SR", sr_bounces=3)
    with pytest.raises(ps.PsbenchError, match="source"):
        predict(np.ones((16, 16, 3), np.float32), lay, source="rays")
