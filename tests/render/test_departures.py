"""Render departures from the solvers' model (psbench.render._departures via render options)."""
import numpy as np
import pytest

import psbench as ps
from psbench._shared.checks import PsbenchError
from psbench.lights import Layout


@pytest.fixture(scope="module")
def surf():
    return ps.make_surface("sombrero", size=32)


LAY = "30x4+60x4"


def _on(s, a):
    return a[:, s.object_mask]


def test_albedo_texture_scales_the_diffuse_term(surf):
    base = ps.render(surf, LAY, model="lambert", shadows=False)
    tex = ps.render(surf, LAY, model="lambert", shadows=False, albedo_texture=0.6, seed=3)
    lit = base.images > 1e-3
    ratio = tex.images[lit] / base.images[lit]
    assert ratio.min() >= 0.4 - 1e-5 and ratio.max() <= 1 + 1e-5
    assert ratio.max() - ratio.min() > 0.4          # the texture spans most of its range
    # the same factor in every image: one texture on the object
    r = np.where(lit, tex.images / np.where(lit, base.images, 1), np.nan)
    np.testing.assert_allclose(np.nanmax(r, 0)[lit.any(0)], np.nanmin(r, 0)[lit.any(0)],
                               rtol=1e-4)


def test_second_material_on_the_right_half(surf):
    one = ps.render(surf, LAY, model="ts")
    two = ps.render(surf, LAY, model="ts", second_material={"rho_s": 0.3, "m": 6.0})
    ref = ps.render(surf, LAY, model="ts", rho_s=0.3, m=6.0)
    W = surf.height.shape[1]
    np.testing.assert_array_equal(two.images[..., : W // 2], one.images[..., : W // 2])
    np.testing.assert_allclose(two.images[..., W // 2:], ref.images[..., W // 2:], rtol=1e-6)
    assert not np.allclose(two.images[..., W // 2:], one.images[..., W // 2:])


def test_saturation_clips_at_the_fraction_of_the_maximum(surf):
    base = ps.render(surf, LAY, noise=0.02, seed=1)
    sat = ps.render(surf, LAY, noise=0.02, seed=1, saturation=0.6)
    top = _on(surf, base.images).max()
    np.testing.assert_allclose(sat.images, np.minimum(base.images, np.float32(0.6 * top)),
                               rtol=1e-6)
    assert (_on(surf, sat.images) >= 0.6 * top * (1 - 1e-6)).any()


def test_gamma_and_ambient(surf):
    base = ps.render(surf, LAY, noise=0.01, seed=2)
    amb = ps.render(surf, LAY, noise=0.01, seed=2, ambient=0.05)
    off = 0.05 * base.dynamic_range.max()
    np.testing.assert_allclose(_on(surf, amb.images), _on(surf, base.images) + off, atol=1e-5)
    assert (amb.images[:, ~surf.object_mask] == 0).all()
    gam = ps.render(surf, LAY, noise=0.01, seed=2, gamma=2.2)
    M = _on(surf, base.images).max()
    want = M * (np.clip(base.images, 0, M) / M) ** (1 / 2.2)
    np.testing.assert_allclose(gam.images, want, rtol=1e-5, atol=1e-6)


def test_light_errors_render_the_perturbed_lights(surf):
    nominal = ps.layout(LAY)
    sc = ps.render(surf, nominal, light_error=2.0, power_error=0.1, seed=5)
    ang = np.degrees(np.arccos(np.clip(np.sum(sc.lights.directions * nominal.directions, 1),
                                       -1, 1)))
    np.testing.assert_allclose(ang, 2.0, atol=1e-6)
    assert np.all(np.abs(sc.lights.power - 1) <= 0.1) and np.ptp(sc.lights.power) > 0.02
    same = Layout(sc.lights.directions, sc.lights.power, nominal.ring, sc.lights.zenith,
                  sc.lights.polar)
    np.testing.assert_array_equal(sc.images, ps.render(surf, same, seed=5).images)
    again = ps.render(surf, nominal, light_error=2.0, power_error=0.1, seed=5)
    np.testing.assert_array_equal(again.images, sc.images)      # seeded
    # the solver given the nominal lights is worse than with the true ones
    truth = ps.solve(sc.images, sc.lights, mask="None", object_mask=surf.object_mask)
    nom = ps.solve(sc.images, nominal, mask="None", object_mask=surf.object_mask)
    e = lambda r: ps.normal_error(r.normals, surf.normals, object_mask=surf.object_mask)  # noqa
    assert e(nom) > e(truth)


def test_light_distance_is_near_lights_along_the_nominal_directions(surf):
    nominal = ps.layout(LAY)
    W = surf.height.shape[1]
    sc = ps.render(surf, nominal, light_distance=3.0, falloff=True)
    ref = ps.render(surf, nominal, light_positions=nominal.directions * 3.0 * W, falloff=True)
    np.testing.assert_array_equal(sc.images, ref.images)
    np.testing.assert_allclose(sc.lights.directions, nominal.directions, atol=1e-12)
    assert not np.allclose(sc.images, ps.render(surf, nominal).images)


def test_eight_bit_quantization_levels(surf):
    sc = ps.render(surf, LAY, noise=0.02, quantize=8)
    top = _on(surf, sc.images).max()
    levels = np.unique(np.rint(_on(surf, sc.images) / top * 255))
    assert levels.size <= 256
    np.testing.assert_allclose(_on(surf, sc.images) / top * 255,
                               np.rint(_on(surf, sc.images) / top * 255), atol=1e-3)


@pytest.mark.parametrize("kw,match", [
    (dict(albedo_texture=1.0), "albedo_texture"), (dict(albedo_texture=-0.1), "albedo_texture"),
    (dict(light_error=45), "light_error"), (dict(power_error=1.0), "power_error"),
    (dict(light_distance=0), "light_distance"), (dict(ambient=-1), "ambient"),
    (dict(saturation=0), "saturation"), (dict(saturation=1.5), "saturation"),
    (dict(gamma=0), "gamma"), (dict(gamma="x"), "gamma"),
    (dict(second_material={"shine": 1}), "second_material"),
    (dict(second_material={"m": 0}), r"second_material\.m"),
    (dict(second_material={}), "second_material"),
    (dict(light_distance=2, light_positions=np.ones((8, 3))), "light_distance"),
])
def test_bad_values_one_line(surf, kw, match):
    with pytest.raises(PsbenchError, match=match) as exc:
        ps.render(surf, LAY, **kw)
    assert "\n" not in str(exc.value)
