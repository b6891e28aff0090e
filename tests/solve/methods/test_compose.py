"""Every method composes with the thesis's masks through the public entry point:
``ps.solve(images, lights, mask="Th" | "Sh", method=NAME)`` uses only the observations
the mask kept, and methods that need more images than given are refused before the
masks run."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError, registry
from psbench.solve import _engine

from _robust_scenes import ROBUST, ts_scene

#: methods solved on the observations a mask keeps (WPS runs the mask per ring)
MASKED = ROBUST + ("ps", "fwlse", "tsfit")


@pytest.fixture(scope="module")
def scene():
    surf, lay, images = ts_scene(32, noise=0.02)
    masks = {m: ps.solve(images, lay, mask=m, object_mask=surf.object_mask)
             for m in ("Th", "Sh")}
    return surf, lay, images, masks


def test_every_registered_method_is_covered():
    assert set(MASKED) | {"wps"} >= set(registry.names("methods")) - _plugins()


def _plugins():
    import importlib
    import pkgutil
    pkg = importlib.import_module("psbench.solve.methods")
    mods = pkgutil.walk_packages(pkg.__path__, pkg.__name__ + ".")  # families' members too
    own = {i.name.rsplit(".", 1)[-1] for i in mods
           if not any(p.startswith("_") for p in i.name.split("."))}
    return set(registry.names("methods")) - own


@pytest.mark.parametrize("name", MASKED)
@pytest.mark.parametrize("mask", ["Th", "Sh"])
def test_solve_composes_with_mask(name, mask, scene):
    surf, lay, images, masks = scene
    om = surf.object_mask
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = ps.solve(images, lay, mask=mask, method=name, object_mask=om)
    base = masks[mask]
    assert res.normals.shape == base.normals.shape
    assert np.isfinite(res.normals).all() and np.isfinite(res.albedo).all()
    used = np.asarray(res.valid, dtype=bool)
    # the method never uses an observation the mask dropped
    assert not (used & ~base.valid)[:, om].any()
    if res.weights is not None:
        w = np.asarray(res.weights)
        assert (w[~base.valid & om[None]] == 0).all()
    ne = ps.normal_error(res.normals, surf.normals, object_mask=om)
    ne_mask = ps.normal_error(base.normals, surf.normals, object_mask=om)
    assert ne < ne_mask + 5.0, (name, mask, ne, ne_mask)


def test_wps_composes_with_mask(scene):
    surf, lay, images, _ = scene
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = ps.solve(images, lay, mask="Th", method="wps", object_mask=surf.object_mask)
    assert np.isfinite(res.normals).all()


@pytest.mark.parametrize("mask", ["None", "Th-Hi-Re-Sh"])
def test_rpca_on_three_images_refused_before_any_work(monkeypatch, mask):
    images = np.random.default_rng(0).random((3, 12, 12)).astype(np.float32)

    def boom(*a, **k):
        raise AssertionError("the masks ran")
    monkeypatch.setattr(_engine, "_masked_ps", boom)
    with pytest.raises(PsbenchError, match=r"method 'rpca' needs at least 4 images, got 3"):
        ps.solve(images, ps.layout("45x3"), mask=mask, method="rpca")


def test_method_warnings_reach_the_result():
    """A method's own warnings (non-convergence) are kept beside the engine's."""
    surf, lay, images = ts_scene(24, noise=0.05)
    with pytest.warns(RuntimeWarning, match="did not converge"):
        res = ps.solve(images, lay, method="cauchy", n_iter=1, object_mask=surf.object_mask)
    assert any("did not converge" in w for w in res.info["warnings"])
