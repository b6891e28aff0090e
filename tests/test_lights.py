import numpy as np
import pytest

import psbench as ps
from psbench.lights import ring_spec

TABLE_2_1 = {5: 16.1645, 15: 5.2779, 30: 2.4495, 45: 1.4142, 60: 1.2247}


@pytest.mark.parametrize("count", [4, 8])
@pytest.mark.parametrize("zenith", sorted(TABLE_2_1))
def test_cond_reproduces_table_2_1(count, zenith):
    assert round(ps.cond(ps.layout(f"{zenith}x{count}")), 4) == TABLE_2_1[zenith]


def test_single_ring_geometry():
    lay = ps.layout("45x8")
    assert lay.k == 8 and lay.n_rings == 1
    np.testing.assert_allclose(lay.zenith, 45.0)
    np.testing.assert_allclose(np.diff(lay.polar), 45.0)
    np.testing.assert_allclose(np.linalg.norm(lay.directions, axis=1), 1.0)
    # polar counter-clockwise from +x: the second light points towards +x,+y
    assert lay.directions[1, 0] > 0 and lay.directions[1, 1] > 0


def test_double_ring_offsets_keep_equal_polar_distances():
    lay = ps.layout("30x8+60x8")
    assert lay.k == 16 and lay.n_rings == 2
    np.testing.assert_allclose(lay.ring_zeniths, [30.0, 60.0])
    allpol = np.sort(lay.polar)
    np.testing.assert_allclose(np.diff(allpol), 22.5)
    lay3 = ps.layout("30x4+45x4+60x4")
    np.testing.assert_allclose(np.diff(np.sort(lay3.polar)), 30.0)
    assert [len(r) for r in lay3.rings()] == [4, 4, 4]


def test_explicit_directions_power_and_subset():
    d = [[0, 0, 1], [1, 0, 1], [0, 1, 1], [-1, -1, 1]]
    lay = ps.layout(d, power=[1, 2, 3, 4])
    np.testing.assert_allclose(np.linalg.norm(lay.S, axis=1), [1, 2, 3, 4])
    sub = lay.subset([1, 2, 3])
    assert sub.k == 3
    np.testing.assert_allclose(sub.power, [2, 3, 4])


@pytest.mark.parametrize("spec, words", [
    ("45x", "malformed"), ("x8", "malformed"), ("90x8", "[0, 90)"), ("-5x8", "malformed"),
    ("45x2", "at least 3"), ("0x8", "degenerate"), ("", "ring notation"),
])
def test_bad_layouts_give_clear_errors(spec, words):
    with pytest.raises(ps.PsbenchError, match=None) as err:
        ps.layout(spec)
    assert words in str(err.value)


def test_bad_explicit_lights():
    with pytest.raises(ps.PsbenchError, match="away from the camera"):
        ps.layout([[0, 0, 1], [1, 0, 1], [0, 1, -1]])
    with pytest.raises(ps.PsbenchError, match="degenerate"):
        ps.layout([[1, 0, 1], [1, 0, 1], [1, 0, 1], [1, 0, 1]])
    with pytest.raises(ps.PsbenchError, match="shape"):
        ps.layout(np.zeros((4, 2)))
    with pytest.raises(ps.PsbenchError, match="power"):
        ps.layout("45x4", power=[1, 2])


def test_ring_spec():
    assert ring_spec("30x4+45x4+60x4") == [(30.0, 4), (45.0, 4), (60.0, 4)]
