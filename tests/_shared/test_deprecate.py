"""Renamed arguments and attributes: the old forms still work, warn, and give the same result."""
from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

import psbench as ps
from psbench import calibrate as cal
from psbench import io, metrics as M
from psbench._shared.deprecation import renamed_args
from psbench.integrate import bilateral_integrate, gradients
from psbench.report import panels
from psbench.render.shadowmap import point_shadow_map


# ----------------------------------------------------------------------------- decorator
@renamed_args(positional=("b", "c"), renamed={"old": "c"})
def _f(a, *, b=1, c=2):
    return a, b, c


def test_new_form_does_not_warn():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert _f(0, b=5, c=6) == (0, 5, 6)
        assert _f(0) == (0, 1, 2)


@pytest.mark.parametrize("call, expect, match", [
    (lambda: _f(0, 5), (0, 5, 2), r"_f\(\): passing b positionally"),
    (lambda: _f(0, 5, 6), (0, 5, 6), "passing b, c positionally"),
    (lambda: _f(0, old=6), (0, 1, 6), r"the keyword old= .* use c=\.\.\. instead"),
    (lambda: _f(0, 5, old=6), (0, 5, 6), "passing b positionally and the keyword old="),
])
def test_old_forms_warn_and_map(call, expect, match):
    with pytest.warns(DeprecationWarning, match=match):
        assert call() == expect


def test_old_forms_conflicts_are_type_errors():
    with pytest.raises(TypeError, match="at most 3 positional"):
        _f(0, 1, 2, 3)
    with pytest.raises(TypeError, match="multiple values for argument 'b'"):
        _f(0, 1, b=2)
    with pytest.raises(TypeError, match="both old= .* and c="):
        _f(0, old=1, c=2)


def test_warning_points_at_the_caller():
    with pytest.warns(DeprecationWarning) as rec:
        _f(0, 5)
    assert rec[0].filename == __file__


def test_signature_shows_the_new_form():
    import inspect
    assert str(inspect.signature(ps.normal_error)) == "(normals, truth, *, object_mask=None)"


# ----------------------------------------------------------------------------- every rename
def _same(a, b):
    if isinstance(a, tuple):
        assert isinstance(b, tuple) and len(a) == len(b)
        for x, y in zip(a, b):
            _same(x, y)
    elif isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            _same(a[k], b[k])
    elif isinstance(a, pd.DataFrame):
        pd.testing.assert_frame_equal(a, b)
    elif isinstance(a, ps.Surface):
        assert a.name == b.name
        for f in ("height", "object_mask", "normals"):
            assert np.array_equal(getattr(a, f), getattr(b, f))
    elif isinstance(a, ps.Layout):
        assert np.array_equal(a.S, b.S) and np.array_equal(a.ring, b.ring)
    else:
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


SURF = ps.make_surface("spheres", size=32)
OBJ = SURF.object_mask.copy()
OBJ[:4] = False
LAY = ps.layout("45x4")
SCENE = ps.render(SURF, LAY, model="ts", noise=0.02, seed=1)
RES = ps.solve(SCENE.images, LAY, mask="Th", object_mask=OBJ)
N, T = RES.normals, SURF.normals
FLAG = ~RES.valid
RING = np.stack([np.ones((32, 32)), 2 * np.ones((32, 32))])
W = np.stack([np.full((32, 32), 0.25), np.full((32, 32), 0.75)])
H = SURF.height
RNG = np.random.default_rng(0)
DARK = RNG.random((24, 24)).astype(np.float32) * 0.01
DARK[3, 4] = 0.9
WHITE = (0.5 + 0.1 * RNG.random((4, 24, 24))).astype(np.float32)
SPH = ps.make_surface("semisphere_disc", size=48)
SPH_IMGS = ps.render(SPH, ps.layout("30x4"), model="phong", phong_m=200, rho_d=0.05,
                     shadows=False).images

CASES = {
    "normal_error positional": (lambda: M.normal_error(N, T, OBJ),
                                lambda: M.normal_error(N, T, object_mask=OBJ)),
    "normal_error mask=": (lambda: ps.normal_error(N, T, mask=OBJ),
                           lambda: ps.normal_error(N, T, object_mask=OBJ)),
    "normal_error_stats": (lambda: M.normal_error_stats(N, T, OBJ),
                           lambda: M.normal_error_stats(N, T, object_mask=OBJ)),
    "ne_by_zenith": (lambda: M.ne_by_zenith(N, T, OBJ, bins=6),
                     lambda: M.ne_by_zenith(N, T, object_mask=OBJ, bins=6)),
    "intensity_error mask=": (lambda: M.intensity_error(SCENE.images, RES, mask=OBJ),
                              lambda: M.intensity_error(SCENE.images, RES, object_mask=OBJ)),
    "weighted_intensity_error": (lambda: M.weighted_intensity_error(RING, W, OBJ),
                                 lambda: M.weighted_intensity_error(RING, W, object_mask=OBJ)),
    "dynamic_range": (lambda: M.dynamic_range(SCENE.images, OBJ),
                      lambda: M.dynamic_range(SCENE.images, object_mask=OBJ)),
    "ie_relative mask=": (lambda: M.ie_relative(SCENE.images, RES, mask=OBJ),
                          lambda: M.ie_relative(SCENE.images, RES, object_mask=OBJ)),
    "quality_factor": (lambda: M.quality_factor(FLAG, SCENE, OBJ),
                       lambda: M.quality_factor(FLAG, SCENE, object_mask=OBJ)),
    "quality_counts mask=": (lambda: M.quality_counts(FLAG, SCENE, mask=OBJ),
                             lambda: M.quality_counts(FLAG, SCENE, object_mask=OBJ)),
    "integrate positional": (lambda: ps.integrate(N, OBJ),
                             lambda: ps.integrate(N, object_mask=OBJ)),
    "integrate mask=": (lambda: ps.integrate(N, mask=OBJ, integrator="fc"),
                        lambda: ps.integrate(N, object_mask=OBJ, integrator="fc")),
    "integrate method=": (lambda: ps.integrate(N, object_mask=OBJ, method="fc"),
                          lambda: ps.integrate(N, object_mask=OBJ, integrator="fc")),
    "solve integrate_method=": (
        lambda: ps.solve(SCENE.images, LAY, mask="Th-Sh", integrate_method="fc", want_height=True).height,
        lambda: ps.solve(SCENE.images, LAY, mask="Th-Sh", integrator="fc", want_height=True).height),
    "bilateral_integrate positional": (
        lambda: bilateral_integrate(N, OBJ, max_iter=3),
        lambda: bilateral_integrate(N, object_mask=OBJ, max_iter=3)),
    "gradients": (lambda: gradients(N, OBJ), lambda: gradients(N, object_mask=OBJ)),
    "shadow_map mask=": (lambda: ps.shadow_map(H, LAY, mask=OBJ),
                         lambda: ps.shadow_map(H, LAY, object_mask=OBJ)),
    "point_shadow_map mask=": (
        lambda: point_shadow_map(H, [[40.0, 0.0, 60.0]], mask=OBJ),
        lambda: point_shadow_map(H, [[40.0, 0.0, 60.0]], object_mask=OBJ)),
    "make_surface positional size": (lambda: ps.make_surface("penny", 24),
                                     lambda: ps.make_surface("penny", size=24)),
    "surface_from_height positional": (lambda: ps.surface_from_height(H, OBJ, "x"),
                                       lambda: ps.surface_from_height(H, object_mask=OBJ,
                                                                      name="x")),
    "surface_from_height mask=": (lambda: ps.surface_from_height(H, mask=OBJ),
                                  lambda: ps.surface_from_height(H, object_mask=OBJ)),
    "Surface(mask=)": (lambda: ps.Surface("s", H, normals=T, mask=OBJ),
                       lambda: ps.Surface("s", H, object_mask=OBJ, normals=T)),
    "Surface.mask": (lambda: SURF.mask, lambda: SURF.object_mask),
    "Scene.object_mask of a surface with .mask": (
        lambda: ps.render(SimpleNamespace(height=H, mask=OBJ, normals=T), LAY).object_mask,
        lambda: ps.render(SimpleNamespace(height=H, object_mask=OBJ, normals=T),
                          LAY).object_mask),
    "render a surface with .mask": (
        lambda: ps.render(SimpleNamespace(height=H, mask=OBJ, normals=T), LAY, noise=0.1).images,
        lambda: ps.render(SimpleNamespace(height=H, object_mask=OBJ, normals=T), LAY,
                          noise=0.1).images),
    "layout positional power": (lambda: ps.layout("45x4", 2.0),
                                lambda: ps.layout("45x4", power=2.0)),
    "encode_normals": (lambda: io.encode_normals(N, OBJ),
                       lambda: io.encode_normals(N, object_mask=OBJ)),
    "panels.encode_normals positional": (lambda: panels.encode_normals(N, OBJ),
                                         lambda: panels.encode_normals(N, object_mask=OBJ)),
    "panels.encode_normals mask=": (lambda: panels.encode_normals(N, mask=OBJ),
                                    lambda: panels.encode_normals(N, object_mask=OBJ)),
    "panels.overlay positional": (
        lambda: panels.overlay(SCENE.images[0], FLAG[0], SCENE.shadow[0], OBJ),
        lambda: panels.overlay(SCENE.images[0], FLAG[0], SCENE.shadow[0], object_mask=OBJ)),
    "panels.overlay mask=": (
        lambda: panels.overlay(SCENE.images[0], FLAG[0], SCENE.shadow[0], mask=OBJ),
        lambda: panels.overlay(SCENE.images[0], FLAG[0], SCENE.shadow[0], object_mask=OBJ)),
    "hot_pixels": (lambda: cal.hot_pixels(DARK, 0.5), lambda: cal.hot_pixels(DARK, threshold=0.5)),
    "remove_hot_pixels": (lambda: cal.remove_hot_pixels(WHITE, DARK > 0.5, 5),
                          lambda: cal.remove_hot_pixels(WHITE, DARK > 0.5, ksize=5)),
    "fit_response": (lambda: cal.fit_response([0.2, 0.5, 0.9], [0.1, 0.4, 0.8], 2),
                     lambda: cal.fit_response([0.2, 0.5, 0.9], [0.1, 0.4, 0.8], degree=2)),
    "polyfit2d": (lambda: cal.polyfit2d(WHITE[0], 2, DARK < 0.5),
                  lambda: cal.polyfit2d(WHITE[0], degree=2, object_mask=DARK < 0.5)),
    "flat_field": (lambda: cal.flat_field(WHITE, 2, mask=DARK < 0.5),
                   lambda: cal.flat_field(WHITE, degree=2, object_mask=DARK < 0.5)),
    "sphere_geometry mask=": (lambda: cal.sphere_geometry(mask=SPH.object_mask),
                              lambda: cal.sphere_geometry(SPH.object_mask)),
    "light_directions_from_sphere": (
        lambda: cal.light_directions_from_sphere(SPH_IMGS, SPH.object_mask),
        lambda: cal.light_directions_from_sphere(SPH_IMGS, object_mask=SPH.object_mask)),
    "light_powers mask=": (lambda: cal.light_powers(WHITE, LAY.directions, mask=DARK < 0.5),
                           lambda: cal.light_powers(WHITE, LAY.directions,
                                                    object_mask=DARK < 0.5)),
}


@pytest.mark.parametrize("name", list(CASES))
def test_old_form_warns_and_gives_the_same_result(name):
    old, new = CASES[name]
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)
        expect = new()
    with pytest.warns(DeprecationWarning, match="deprecated"):
        got = old()
    _same(got, expect)


def _files(folder):
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_io_writers_old_forms(tmp_path):
    imgs = SCENE.images.clip(0, 1)
    io.write_dataset(tmp_path / "new", imgs, LAY, object_mask=OBJ, normals=T)
    with pytest.warns(DeprecationWarning, match="positionally"):
        io.write_dataset(tmp_path / "old", imgs, LAY, OBJ, T)
    with pytest.warns(DeprecationWarning, match="mask="):
        io.write_dataset(tmp_path / "kw", imgs, LAY, mask=OBJ, normals=T)
    assert _files(tmp_path / "old") == _files(tmp_path / "new") == _files(tmp_path / "kw")

    io.write_outputs(tmp_path / "out_new", RES, object_mask=OBJ)
    with pytest.warns(DeprecationWarning, match="mask="):
        io.write_outputs(tmp_path / "out_old", RES, mask=OBJ)
    assert _files(tmp_path / "out_old") == _files(tmp_path / "out_new")

    io.write_ply(tmp_path / "new.ply", H, object_mask=OBJ)
    with pytest.warns(DeprecationWarning):
        io.write_ply(tmp_path / "old.ply", H, OBJ)
    assert (tmp_path / "old.ply").read_bytes() == (tmp_path / "new.ply").read_bytes()

    io.write_image(tmp_path / "new.png", imgs[0], bits=8)
    with pytest.warns(DeprecationWarning):
        io.write_image(tmp_path / "old.png", imgs[0], 8)
    assert (tmp_path / "old.png").read_bytes() == (tmp_path / "new.png").read_bytes()


def test_dataset_mask_alias(tmp_path):
    io.write_dataset(tmp_path / "ds", SCENE.images.clip(0, 1), LAY, object_mask=OBJ)
    ds = io.read_dataset(tmp_path / "ds")
    assert np.array_equal(ds.object_mask, OBJ)
    with pytest.warns(DeprecationWarning, match="Dataset.mask"):
        assert ds.mask is ds.object_mask
    with pytest.warns(DeprecationWarning, match="Dataset.mask"):
        ds.mask = ~OBJ
    assert np.array_equal(ds.object_mask, ~OBJ)
    with pytest.warns(DeprecationWarning, match="Dataset"):
        old = io.Dataset(ds.images, ds.lights, normals=None, names=ds.names, mask=OBJ)
    assert old.object_mask is OBJ
    with pytest.raises(TypeError, match="both"):
        io.Dataset(ds.images, ds.lights, OBJ, None, ds.names, mask=OBJ)


# ----------------------------------------------------------------------------- renamed names
@pytest.mark.parametrize("module, old, new", [
    ("psbench.analysis", "KINDS", "IMAGE_KINDS"),
    ("psbench.analysis.builtin", "KINDS", "IMAGE_KINDS"),
    ("psbench.analysis._common", "KINDS", "IMAGE_KINDS"),
    ("psbench.report.present", "KINDS", "CELL_KINDS"),
    ("psbench.report.present", "kind", "cell_kind"),
    ("psbench.report.gate", "metric_kind", "cell_kind"),
    ("psbench.integrate", "METHODS", "INTEGRATORS"),
    ("psbench.forensic.pipeline", "METHODS", "RECIPES"),
    ("psbench.harness.run", "KINDS", "RUN_KINDS"),
])
def test_renamed_module_names(module, old, new):
    import importlib
    mod = importlib.import_module(module)
    assert old not in getattr(mod, "__all__", ())      # star imports do not warn
    with pytest.warns(DeprecationWarning, match=f"{module}.{old} is deprecated.*{new}"):
        value = getattr(mod, old)
    assert value is getattr(mod, new)
    with pytest.warns(DeprecationWarning, match=new):
        exec(f"from {module} import {old}", {})
    with pytest.raises(AttributeError, match="no attribute"):
        getattr(mod, old + "_NOPE")
