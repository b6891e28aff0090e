"""The ne_map run extra: encoding, decoding, and its column in a solve row."""
from __future__ import annotations

import numpy as np
import pytest

from psbench.harness import nemap, run
from psbench.harness.schema import row_table


def test_round_trip_keeps_values_and_outside():
    e = np.linspace(0, 30, 40 * 50, dtype=np.float32).reshape(40, 50)
    e[0, 0] = 150.0                                    # clipped at CLIP
    m = np.ones(e.shape, bool)
    m[30:, :] = False
    d = nemap.decode(nemap.encode(e, m))
    assert d.shape == (40, 50) and d.dtype == np.float32
    assert np.isnan(d[30:]).all() and np.isfinite(d[:30]).all()
    np.testing.assert_allclose(d[:30][1:], e[:30][1:], atol=0.006)
    assert d[0, 0] == nemap.CLIP
    assert nemap.decode(None) is None and nemap.decode(float("nan")) is None


def test_large_maps_are_reduced_over_the_object_only():
    H, W = 612, 512
    e = np.full((H, W), 7.0, np.float32)
    m = np.zeros((H, W), bool)
    m[100:500, 50:300] = True
    e[~m] = 80.0                                       # background must not leak in
    d = nemap.decode(nemap.encode(e, m))
    assert max(d.shape) <= nemap.MAX_SIDE and d.shape == (160, 134)
    inside = np.isfinite(d)
    assert abs(inside.mean() - m.mean()) < 0.02
    np.testing.assert_allclose(d[inside], 7.0, atol=0.006)


def test_solve_row_carries_the_map():
    p = run.normalize({"surface": "semisphere_disc", "size": 200, "mask": "None", "zenith": 45,
                       "count": 8, "noise": 0.05, "seed": 1, "extras": ["ne_map"]})
    row = run.execute(p, sweep="x")
    assert row["status"] == "ok", row.get("traceback")
    d = nemap.decode(row["ne_map"])
    assert d.shape == (160, 160)
    assert np.isnan(d).any() and np.isfinite(d).mean() > 0.5          # disc of the object
    assert row["ne_mean"] > 0.5                                       # noise: a real error
    assert np.nanmean(d) == pytest.approx(row["ne_mean"], rel=0.05)
    assert row_table([row]).column("ne_map")[0].as_py() == row["ne_map"]
    plain = run.execute(run.normalize({**p, "extras": []}), sweep="x")
    assert plain.get("ne_map") is None
