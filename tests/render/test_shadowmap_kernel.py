"""The compiled passes of the shadow-map sweep against their numpy formulation."""
import numba
import numpy as np
import pytest

from psbench.render import _shadowmap_kernel as k
from psbench.render.shadowmap import shadow_map


def _lift_running_max_ref(g, lift):
    g = g + lift[:, None]
    for w in range(1, g.shape[0]):
        np.maximum(g[w], g[w - 1], out=g[w])
    return g


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_lift_running_max_is_bit_identical(dtype):
    rng = np.random.default_rng(0)
    g = (rng.normal(size=(57, 611)) * 10).astype(dtype)
    g[3, :40] = -1e30  # the floor outside the image
    lift = (np.arange(57) * 0.37 - 1).astype(dtype)
    want = _lift_running_max_ref(g, lift)
    got = k.lift_running_max(g.copy(), lift)
    assert got.dtype == dtype and np.array_equal(got, want)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_above_is_bit_identical(dtype):
    rng = np.random.default_rng(1)
    H, W = 40, 33
    horizon = rng.normal(size=(H, W)).astype(dtype)
    hb = rng.normal(size=(H, W)).astype(np.float32)
    rowpart = (rng.normal(size=H) * 0.1).astype(dtype)
    colpart = (rng.normal(size=W) * 0.1).astype(dtype)
    thr = np.empty((H, W), dtype=dtype)
    np.add(hb, rowpart[:, None], out=thr)
    thr += colpart[None, :]
    got = k.above(horizon, hb, rowpart, colpart, np.zeros((H, W), dtype=bool))
    assert np.array_equal(got, horizon > thr)


def test_maps_do_not_depend_on_numba_threads():
    rng = np.random.default_rng(2)
    h = rng.normal(size=(90, 70)).cumsum(axis=0).astype(np.float32)
    d = [[1.0, 0.3, 0.8], [-0.2, -1.0, 0.5], [0.7, 0.7, 1.5]]
    n0 = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = shadow_map(h, d, bias=0.2)
        numba.set_num_threads(n0)
        many = shadow_map(h, d, bias=0.2)
    finally:
        numba.set_num_threads(n0)
    assert one.any() and np.array_equal(one, many)
