"""robust: per pixel the better (truncated loss) of a trimmed Lambertian fit and a
Lambert + Torrance-Sparrow fit."""
from __future__ import annotations

import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError
from psbench.solve.methods.tsfit import _lm
from psbench.solve.methods.tsfit import _aux_kernel as kx
from psbench.solve.methods.robust import RobustOptions

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


def _choice(images, lay, bt, rs, m, bl, valid, cap, pix=None):
    k, P = images.shape
    f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
    args = (_lm.Lights(lay.directions, lay.power).table, f32(bt), f32(np.full(P, rs)),
            f32(np.full(P, m)), f32(bl), f32(images), valid, bool(valid.all()))
    if pix is not None:
        out = np.empty((k, pix.size), np.float32), np.empty((k, pix.size), np.float32)
        kx.choice_sample(*args, pix, *out)
    else:
        out = np.empty(P), np.empty(P)
        kx.choice_losses(*args, cap, *out)
    return out


def test_choice_residuals_match_the_renderer_and_numpy():
    """The model the choice is made with is the renderer's Torrance-Sparrow model, and
    the truncated losses are sum_i min(r_i^2, cap) over the valid observations."""
    surf = ps.make_surface("sombrero2", size=24)
    lay = ps.layout("30x8+60x8", power=np.linspace(0.7, 1.3, 16))
    sc = ps.render(surf, lay, model="ts", shadows="self", rho_d=0.7, rho_s=0.4, m=3.0)
    om = surf.object_mask
    images = sc.images[:, om]
    bt = (0.7 * surf.normals[om]).T
    bl = 0.8 * bt
    valid = np.random.default_rng(0).random(images.shape) > 0.2
    pix = np.arange(images.shape[1])
    rt, rl = _choice(images, lay, bt, 0.4, 3.0, bl, valid, 0, pix)
    assert np.nanmax(rt) < 2e-5                      # the rendered images, exactly
    ref_l = np.abs(images - lay.S @ bl)              # the Lambertian fit: unclamped
    np.testing.assert_allclose(rl[valid], ref_l[valid], rtol=1e-5, atol=1e-6)
    assert np.isnan(rl[~valid]).all() and np.isnan(rt[~valid]).all()
    cap = float(np.percentile(ref_l[valid], 70)) ** 2
    lt, ll = _choice(images, lay, bt, 0.4, 3.0, bl, valid, cap)
    np.testing.assert_allclose(ll, np.where(valid, np.minimum(ref_l ** 2, cap), 0).sum(0),
                               rtol=1e-5)
    assert (lt < 1e-8).all()


@pytest.mark.parametrize("kw", [{"c": 0}, {"c": -1}, {"model": "phong"}])
def test_option_ranges(kw):
    with pytest.raises(PsbenchError, match=next(iter(kw))):
        RobustOptions(**kw)
