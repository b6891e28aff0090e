"""Tests for psbench.solve.subset (CJ, xNL, RA subset masks)."""
import itertools

import numpy as np
import pytest

from psbench._shared.checks import PsbenchError
from psbench.lights import layout
from psbench.solve import kernel, subset


def _angle_deg(a, b):
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(c, (a * b).sum(-1)))


def _dome(H=48, slope=0.6):
    yy, xx = np.mgrid[-1:1:H * 1j, -1:1:H * 1j]
    n = np.stack([xx * slope, -yy * slope, np.ones_like(xx)], -1)
    return (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)


def _lambert(n, S, rho=1.0):
    return np.asarray(kernel.lambert((rho * n).astype(np.float32), S), dtype=np.float32)


def _pixel(values):
    """(k,) intensities -> (k, 1, 2) stack: the pixel plus a black pixel, so that each
    image's dynamic range is the pixel's own value."""
    v = np.asarray(values, dtype=np.float32)
    return np.stack([v, np.zeros_like(v)], axis=1)[:, None, :]


# ----------------------------------------------------------------------------- RA
def test_n_ransac_thesis_value():
    assert subset.n_ransac() == 35
    assert subset.n_ransac(p=0.99, eps=0.5, s=3) == 35
    assert subset.n_ransac(eps=0.0) == 1
    with pytest.raises(PsbenchError):
        subset.n_ransac(p=1.0)


def test_ransac_uses_all_triplets_when_few():
    S7 = layout("45x7").S
    trip = subset._triplets(S7, None, 0)
    assert trip.shape == (35, 3)
    assert {tuple(t) for t in trip} == set(itertools.combinations(range(7), 3))


def test_ransac_draws_35_distinct_seeded_triplets():
    S = layout("30x8+60x8").S
    a = subset._triplets(S, None, 0)
    b = subset._triplets(S, None, 0)
    c = subset._triplets(S, None, 1)
    assert a.shape == (35, 3)
    assert len({tuple(t) for t in a}) == 35
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_ransac_noiseless_lambert_is_exact():
    lay = layout("30x8+60x8")
    n = _dome()
    I = _lambert(n, lay.S)
    valid = subset.ransac(I, lay.S, threshold=0.05)
    assert valid.all()
    nn, _ = kernel.split(kernel.wls(I, lay.S, valid))
    assert _angle_deg(nn, n).max() < 0.01


def test_ransac_rejects_planted_outliers():
    lay = layout("45x8")
    n = np.array([[[0.2, 0.1, 1.0]]], dtype=np.float32)
    n /= np.linalg.norm(n)
    I = _lambert(n, lay.S)[:, 0, 0]
    assert I[5] > 0.2
    I[2] += 0.8   # highlight
    I[5] = 0.0    # shadow (true value is positive)
    valid = subset.ransac(_pixel(I), lay.S, threshold=0.05)
    assert valid[:, 0, 0].tolist() == [i not in (2, 5) for i in range(8)]


def test_ransac_bad_input():
    with pytest.raises(PsbenchError):
        subset.ransac(np.zeros((8, 4, 4), np.float32), layout("45x7").S)
    with pytest.raises(PsbenchError):
        subset.ransac(np.zeros((8, 4, 4), np.float32), layout("45x8").S, threshold=-1)


# ----------------------------------------------------------------------------- CJ
def test_cj_noiseless_exact_and_needs_four():
    lay = layout("45x4")
    n = _dome()
    I = _lambert(n, lay.S, rho=0.7)
    b = subset.cj(I, lay.S)
    nn, rho = kernel.split(b)
    assert _angle_deg(nn, n).max() < 0.01
    assert np.allclose(rho, 0.7, atol=1e-4)
    with pytest.raises(PsbenchError):
        subset.cj(np.zeros((5, 2, 2), np.float32), layout("45x5").S)


def test_cj_picks_triplet_without_planted_highlight():
    lay = layout("45x4")
    n = np.array([0.15, -0.1, 1.0]); n /= np.linalg.norm(n)
    for hi in range(4):
        I = _lambert(n[None, None].astype(np.float32), lay.S)
        I[hi] += 0.6
        b = subset.cj(I, lay.S)
        nn, _ = kernel.split(b)
        assert _angle_deg(nn[0, 0], n) < 0.01, hi
        # the triplet solutions that contain the highlight are all wrong
        assert _angle_deg(kernel.split(kernel.ls(I, lay.S))[0][0, 0], n) > 1.0


# ----------------------------------------------------------------------------- xNL
def test_null_vector_closed_form():
    S4 = layout("30x2+60x2").S
    a = subset.null_vector(S4)
    assert np.allclose(a @ S4, 0, atol=1e-12)
    assert np.isclose(np.linalg.norm(a), 1.0)


def test_xnl_noiseless_lambert_is_exact():
    lay = layout("30x8+60x8")
    n = _dome()
    I = _lambert(n, lay.S)
    valid = subset.xnl(I, lay.S, t_nl=0.01)
    assert valid.all()
    nn, _ = kernel.split(kernel.wls(I, lay.S, valid))
    assert _angle_deg(nn, n).max() < 0.01


def _k8_case():
    """k = 8 pixel with the darkest observation shadowed and the brightest two
    highlighted, plus (optionally) a highlight pair that is mutually consistent."""
    lay = layout("45x8")
    n = np.array([0.25, 0.1, 1.0]); n /= np.linalg.norm(n)
    I = _lambert(n[None, None].astype(np.float32), lay.S)[:, 0, 0].astype(np.float64)
    order = np.argsort(I)
    return lay, n, I, order


def test_xnl_thesis_pattern_01100_k8():
    lay, n, I, order = _k8_case()
    J = I.copy()
    J[order[0]] = 0.0                 # darkest: shadow
    J[order[6]] += 0.5                # brightest two: highlights
    J[order[7]] += 0.9
    valid, pattern = subset.xnl(_pixel(J), lay.S, t_nl=0.001, return_pattern=True)
    assert pattern[:, 0, 0].astype(int).tolist() == [0, 1, 1, 0, 0]
    expect = np.ones(8, bool)
    expect[[order[0], order[6], order[7]]] = False
    assert valid[:, 0, 0].tolist() == expect.tolist()


def _broken_case():
    """Pattern [0 1 1 0 1]: shadow at the darkest, and highlights on sorted positions 6
    and 7 chosen so that the brightest quadruple (4..7) still looks Lambertian."""
    lay, n, I, order = _k8_case()
    S = lay.S
    a = subset.null_vector(S[order[4:8]])
    assert a[2] * a[3] < 0  # the pair can cancel
    J = I.copy()
    J[order[0]] = 0.0
    d6 = 0.4
    d7 = -a[2] / a[3] * d6
    J[order[6]] += d6
    J[order[7]] += d7
    assert np.array_equal(np.argsort(J)[1:], order[1:])
    return lay, n, J, order


def test_xnl_broken_pattern_corrected_to_highlights():
    lay, n, J, order = _broken_case()
    nh = np.broadcast_to(n.astype(np.float32), (1, 2, 3))
    # t_re = 90: every observation passes the Re test -> some of the brightest four is
    # a highlight -> [0 1 1 0 0]
    valid, pattern = subset.xnl(_pixel(J), lay.S, t_nl=0.001, t_re=90.0, normals_hint=nh,
                                return_pattern=True)
    assert pattern[:, 0, 0].astype(int).tolist() == [0, 1, 1, 0, 1]
    expect = np.zeros(8, bool)
    expect[order[1:6]] = True
    assert valid[:, 0, 0].tolist() == expect.tolist()


def test_xnl_broken_pattern_corrected_to_shadows():
    lay, n, J, order = _broken_case()
    nh = np.broadcast_to(n.astype(np.float32), (1, 2, 3))
    valid = subset.xnl(_pixel(J), lay.S, t_nl=0.001, t_re=0.0, normals_hint=nh)
    expect = np.zeros(8, bool)
    expect[order[4:8]] = True           # [0 0 0 0 1]
    assert valid[:, 0, 0].tolist() == expect.tolist()


def test_xnl_resolve_general_rule():
    P = np.array([[0, 1, 1, 0, 1]], bool).T
    none = np.zeros((8, 1), bool)
    allhi = np.ones((8, 1), bool)
    v, f, l = subset.xnl_resolve(P, none)
    assert v[:, 0].astype(int).tolist() == [0, 0, 0, 0, 1, 1, 1, 1] and (f[0], l[0]) == (4, 4)
    v, f, l = subset.xnl_resolve(P, allhi)
    assert v[:, 0].astype(int).tolist() == [0, 1, 1, 1, 1, 1, 0, 0] and (f[0], l[0]) == (1, 2)
    # three runs, highlight only among the brightest: the middle run is kept
    P3 = np.array([[1, 0, 1, 0, 0, 1]], bool).T       # k = 9
    hi = np.zeros((9, 1), bool); hi[8] = True
    v, f, l = subset.xnl_resolve(P3, hi)
    assert (int(f[0]), int(l[0])) == (2, 2)
    assert v[:, 0].astype(int).tolist() == [0, 0, 1, 1, 1, 1, 0, 0, 0]
    # proper patterns: leading zeros -> shadows, trailing zeros -> highlights
    v, _, _ = subset.xnl_resolve(np.array([[0, 0, 1, 1, 1]], bool).T, allhi)
    assert v[:, 0].astype(int).tolist() == [0, 0, 1, 1, 1, 1, 1, 1]
    # no Lambertian quadruple: the least-error quadruple is kept
    err = np.array([[5, 4, 1, 3, 9]], float).T
    v, f, l = subset.xnl_resolve(np.zeros((5, 1), bool), allhi, err)
    assert (int(f[0]), int(l[0])) == (2, 2)


def test_xnl_needs_four_images():
    with pytest.raises(PsbenchError):
        subset.xnl(np.zeros((3, 2, 2), np.float32), layout("45x3").S, t_nl=0.02)


def test_t_re_default_eq_5_1():
    assert np.isclose(subset.t_re_default(layout("45x8").S), 22.5)
    assert np.isclose(subset.t_re_default(layout("30x8+60x8").S), 15.0)
    assert np.isclose(subset.t_re_default(layout("20x4").S), 20.0)
