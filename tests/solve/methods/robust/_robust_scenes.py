"""Scenes and helpers shared by the robust-method tests (not a test module)."""
from __future__ import annotations

import importlib
import warnings

import numpy as np

import psbench as ps
from psbench.solve import kernel
from psbench.solve.base import Problem

#: the robust methods under test
ROBUST = ("l1", "sbl", "rpca", "huber", "cauchy", "tukey", "trim", "robust")


def problem(images, lights, valid=None, object_mask=None, scale=None):
    """A Problem as the masked-PS engine builds it (start = masked least squares,
    scale = mean dynamic range of the images unless given)."""
    images = np.ascontiguousarray(images, dtype=np.float32)
    k, H, W = images.shape
    valid = np.ones((k, H, W), dtype=bool) if valid is None else valid
    om = np.ones((H, W), dtype=bool) if object_mask is None else object_mask
    if scale is None:
        f = images.reshape(k, -1)
        scale = float((f.max(axis=1) - f.min(axis=1)).mean()) or 1.0
    S = lights.S
    return Problem(images=images, lights=lights, valid=valid, object_mask=om, scale=scale,
                   _start=lambda: kernel.wls(images, S, valid))


def spec(name):
    """The ``METHOD`` of a robust family member's own module (``robust`` is the family's)."""
    family = "psbench.solve.methods.robust"
    return importlib.import_module(family if name == "robust" else f"{family}.{name}").METHOD


def fit(name, prob, *, quiet=True, **options):
    m = spec(name)
    opts = m.options.build(options, method=name)
    with warnings.catch_warnings():
        if quiet:
            warnings.simplefilter("ignore", RuntimeWarning)
        return m.func(prob, opts)


def ne(b, truth, object_mask):
    return ps.normal_error(kernel.split(np.asarray(b, dtype=np.float32))[0], truth,
                           object_mask=object_mask)


def lambert_scene(size=48, lights="30x8+60x8", zenith=28.0):
    """Lambertian images without shadows under the 16-light rig layout: sombrero1's
    height scaled so that its normals reach ``zenith`` degrees (< 90 - 60), so every
    s . n > 0 and least squares on clean images is exact."""
    base = ps.make_surface("sombrero1", size=size)
    z0 = np.arccos(base.normals[..., 2][base.object_mask].min())
    surf = ps.surface_from_height(base.height * (np.tan(np.radians(zenith)) / np.tan(z0)),
                                  object_mask=base.object_mask)
    lay = ps.layout(lights)
    images = ps.render(surf, lay, model="lambert", shadows="self").images
    assert (images[:, surf.object_mask] > 0).all()
    return surf, lay, images


def corrupt(images, fraction=0.2, seed=1):
    """Set ``fraction`` of the observations, at random, to 0 or to 3x their value
    (half each)."""
    rng = np.random.default_rng(seed)
    out = images.copy()
    hit = rng.random(images.shape) < fraction
    up = rng.random(images.shape) < 0.5
    out[hit & up] *= 3.0
    out[hit & ~up] = 0.0
    return out, hit


def ts_scene(size=40, lights="30x8+60x8", noise=0.0):
    """Torrance-Sparrow sombrero2 with self and cast shadows (the thesis's model)."""
    surf = ps.make_surface("sombrero2", size=size)
    lay = ps.layout(lights)
    images = ps.render(surf, lay, model="ts", shadows=True, noise=noise, seed=0).images
    return surf, lay, images
