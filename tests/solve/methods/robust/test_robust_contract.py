"""Contract tests shared by every robust method: registration, exactness on clean
Lambertian data, composition with mask validity, the Fit they return, convergence
reporting and option errors."""
from __future__ import annotations

import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError, registry
from psbench.solve.base import Fit, Options

from _robust_scenes import ROBUST, fit, lambert_scene, ne, problem, spec, ts_scene

ITERATIVE = ("l1", "sbl", "huber", "cauchy", "tukey", "robust", "rpca")


@pytest.fixture(scope="module")
def clean():
    return lambert_scene(32)


@pytest.fixture(scope="module")
def ts():
    surf, lay, images = ts_scene(40, noise=0.02)
    out = {}
    for mask in ("Th", "Sh"):
        out[mask] = ps.solve(images, lay, mask=mask, object_mask=surf.object_mask).valid
    return surf, lay, images, out


@pytest.mark.parametrize("name", ROBUST)
def test_registered_with_documented_options(name):
    m = registry.get("methods", name)
    assert m is spec(name)
    assert m.masked and m.help
    assert issubclass(m.options, Options)
    doc = m.options.__doc__ or ""
    own = [f for f in m.options.names() if f not in Options.names()]
    for field in own:
        assert field in doc or field in (type.mro(m.options)[1].__doc__ or ""), field
    import sys
    mod = sys.modules[m.func.__module__]
    assert "Source" in mod.__doc__ or "Sources" in mod.__doc__


@pytest.mark.parametrize("name", ROBUST)
def test_noiseless_lambertian_is_exact(name, clean):
    surf, lay, images = clean
    f = fit(name, problem(images, lay, object_mask=surf.object_mask))
    assert ne(f.b, surf.normals, surf.object_mask) < 0.01


@pytest.mark.parametrize("name", ROBUST)
def test_fit_contract(name, clean):
    surf, lay, images = clean
    om = surf.object_mask.copy()
    om[:, :5] = False
    images = images.copy()
    images[:, ~om] = 7.0                      # background must not matter
    f = fit(name, problem(images, lay, object_mask=om))
    k, H, W = images.shape
    assert isinstance(f, Fit)
    assert f.b.shape == (H, W, 3) and f.b.dtype == np.float32
    assert np.isfinite(f.b).all() and (f.b[~om] == 0).all()
    assert f.valid is not None or f.weights is not None
    if f.valid is not None:
        assert f.valid.shape == (k, H, W) and f.valid.dtype == bool
    if f.weights is not None:
        assert f.weights.shape == (k, H, W) and f.weights.dtype == np.float32
        assert f.weights.min() >= 0 and f.weights.max() <= 1
        assert (f.weights[:, ~om] == 0).all()
    if np.ndim(f.iterations):
        assert f.iterations.shape == (H, W) and (f.iterations[~om] == 0).all()
        assert np.asarray(f.converged).shape == (H, W)
    assert ne(f.b, surf.normals, om) < 0.01


@pytest.mark.parametrize("name", ROBUST)
@pytest.mark.parametrize("mask", ["Th", "Sh"])
def test_composes_with_mask_validity(name, mask, ts):
    """The method sees only the observations the mask kept: what the others hold
    does not change its result, and the inliers it reports are among them."""
    surf, lay, images, valid = ts
    v = valid[mask]
    assert not v[:, surf.object_mask].all()
    p1 = problem(images, lay, valid=v, object_mask=surf.object_mask, scale=1.0)
    junk = images.copy()
    junk[~v] = np.random.default_rng(3).random(int((~v).sum())).astype(np.float32) * 5
    p2 = problem(junk, lay, valid=v, object_mask=surf.object_mask, scale=1.0)
    f1, f2 = fit(name, p1), fit(name, p2)
    assert np.isfinite(f1.b).all()
    np.testing.assert_allclose(f1.b, f2.b, rtol=0, atol=1e-5)
    if f1.valid is not None:
        assert not (f1.valid & ~v)[:, surf.object_mask].any()
    if f1.weights is not None:
        assert (f1.weights[~v & surf.object_mask[None]] == 0).all()
    l2 = ne(p1.start(), surf.normals, surf.object_mask)
    assert ne(f1.b, surf.normals, surf.object_mask) < l2 + 5.0


@pytest.mark.parametrize("name", ITERATIVE)
def test_non_convergence_is_reported_and_warned(name):
    surf, lay, images = ts_scene(24, noise=0.05)
    with pytest.warns(RuntimeWarning) as rec:
        f = fit(name, problem(images, lay, object_mask=surf.object_mask), quiet=False, n_iter=1)
    assert any("did not converge" in str(w.message) for w in rec)
    conv = np.asarray(f.converged)
    assert not conv.all()
    assert np.isfinite(f.b).all()
    assert any("did not converge" in w for w in f.info.get("warnings", []))


@pytest.mark.parametrize("name", ROBUST)
def test_no_nan_on_dark_and_degenerate_pixels(name):
    surf, lay, images = lambert_scene(24)
    images = images.copy()
    images[:, :6, :6] = 0.0                   # black patch: albedo 0
    images[:, 10, 10] = images[:, 10, 10].mean()  # constant pixel
    valid = np.ones(images.shape, dtype=bool)
    valid[4:, 12:, 12:] = False               # only 4 observations left there
    f = fit(name, problem(images, lay, valid=valid, object_mask=surf.object_mask))
    assert np.isfinite(f.b).all()
    assert np.abs(f.b[:6, :6]).max() < 1e-6


@pytest.mark.parametrize("name", ROBUST)
def test_unknown_option_lists_valid_ones(name):
    with pytest.raises(PsbenchError, match=r"unknown option\(s\) 'bogus'.*valid options: .*max_iter"):
        spec(name).options.build({"bogus": 1}, method=name)


@pytest.mark.parametrize("name", ITERATIVE)
@pytest.mark.parametrize("n_iter", [0, -3, 2.5, True])
def test_iteration_count_must_be_positive_integer(name, n_iter):
    with pytest.raises(PsbenchError, match="n_iter"):
        spec(name).options(n_iter=n_iter)


@pytest.mark.parametrize("name", ITERATIVE)
@pytest.mark.parametrize("tol", [0.0, -1e-3, float("nan")])
def test_tolerance_must_be_positive(name, tol):
    with pytest.raises(PsbenchError, match="tol"):
        spec(name).options(tol=tol)


def test_errors_are_one_line():
    for name, kw in [("trim", {"drop_dark": 0.5}), ("robust", {"c": 0}),
                     ("sbl", {"sigma": 0}), ("rpca", {"rank": 0}), ("cauchy", {"c": -1}),
                     ("tukey", {"start": "median"}), ("l1", {"eps": 0})]:
        with pytest.raises(PsbenchError) as e:
            spec(name).options(**kw)
        assert "\n" not in str(e.value) and next(iter(kw)) in str(e.value)
