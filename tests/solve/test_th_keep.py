"""Th's th_keep option: each pixel keeps at least a fraction of its observations."""
from __future__ import annotations

import numpy as np
import pytest

import psbench as ps
from psbench.solve.masks.th import keep_at_least, th


def test_keep_at_least_gives_back_the_closest_to_the_bounds():
    # one pixel, 8 observations: bounds [0.2, 0.6]; only 0.3 is inside
    i = np.array([0.0, 0.3, 0.9, 0.65, 0.1, 1.0, 0.15, 0.95], np.float32)[:, None]
    valid = (i >= 0.2) & (i <= 0.6)
    keep_at_least(i, valid, np.float32(0.2), np.float32(0.6), np.float32(1.0), 0.5)
    # q = 4: 0.3 (inside), then 0.65 (0.05 out), 0.15 (0.05 out), 0.1 (0.1 out)
    assert sorted(i[valid[:, 0], 0].tolist()) == pytest.approx([0.1, 0.15, 0.3, 0.65])


def test_keep_at_least_leaves_pixels_that_keep_enough():
    i = np.random.default_rng(0).random((8, 5), dtype=np.float32)
    valid = np.ones_like(i, dtype=bool)
    valid[0] = False
    before = valid.copy()
    keep_at_least(i, valid, np.float32(0.2), np.float32(0.6), np.float32(1.0), 0.5)
    assert (valid == before).all()


def test_th_keep_through_solve_keeps_the_fraction():
    surf = ps.make_surface("sombrero2", size=32)
    scene = ps.render(surf, ps.layout("30x8+60x8"), model="ts", noise=0.0)
    om = surf.object_mask
    lit = ps.solve(scene.images, scene.lights, mask="Th", object_mask=om)
    kept = ps.solve(scene.images, scene.lights, mask="Th", object_mask=om,
                    thresholds={"th_keep": 0.75})
    n_lit = lit.valid[:, om].sum(axis=0)
    n_kept = kept.valid[:, om].sum(axis=0)
    assert (n_kept >= 12).all() and (n_kept >= n_lit).all()
    assert (n_lit < 12).any()                        # the option changed something


def test_th_keep_only_gives_observations_back():
    surf = ps.make_surface("sombrero2", size=32)
    images = ps.render(surf, ps.layout("30x8+60x8"), model="ts", noise=0.0).images
    flat = images.reshape(16, -1)
    lo = flat.min(axis=1)[:, None, None]
    rng = flat.max(axis=1)[:, None, None] - lo
    literal = th(images, lo, rng, 0.08, 0.35)
    kept = keep_at_least(images, literal.copy(), lo + np.float32(0.08) * rng,
                         lo + np.float32(0.35) * rng, rng, 0.75)
    assert not (literal & ~kept).any()
    assert (kept.sum(axis=0) >= 12).all() and (kept != literal).any()
