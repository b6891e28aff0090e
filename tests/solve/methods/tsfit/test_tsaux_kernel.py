"""tsfit's compiled helpers (dark-observation weights, neighbour statistics) against
numpy references, and independent of the number of threads."""
from __future__ import annotations

import numba
import numpy as np
import pytest

import psbench as ps
from psbench.solve.methods.tsfit import _lm, _prop as _tsprop
from psbench.solve.methods.tsfit._start import put_back


def _pixels(p=5000, seed=0):
    rng = np.random.default_rng(seed)
    lay = ps.layout("30x8+60x8", power=np.linspace(0.6, 1.4, 16))
    L = _lm.Lights(lay.directions, lay.power)
    n = rng.normal(size=(3, p))
    n[2] = np.abs(n[2]) + 0.2
    n = (n / np.linalg.norm(n, axis=0)).astype(np.float32)
    rd = rng.uniform(0.2, 1.0, p).astype(np.float32)
    rs = rng.uniform(0.0, 0.8, p).astype(np.float32)
    m = rng.uniform(1.5, 6.0, p).astype(np.float32)
    f = _lm.predict(L, n, rd, rs, m)
    I = f + rng.normal(0, 0.03, f.shape).astype(np.float32)
    I[rng.random(f.shape) < 0.1] *= 0.1  # cast shadows
    valid = rng.random(f.shape) > 0.05
    return L, n, rd, rs, m, I, valid


def _reference(I, valid, pred, sigma, ratio, sigmas):
    margin = (np.float32(sigmas) * sigma)[:, None]
    dark = (I < np.float32(ratio) * pred) & (I < pred - margin) & (pred > margin)
    return valid & ~dark


@pytest.mark.parametrize("lobe", [True, False])
def test_dark_weights_match_numpy(lobe):
    L, n, rd, rs, m, I, valid = _pixels()
    sigma = np.linspace(0.01, 0.05, L.k).astype(np.float32)
    if lobe:
        pred = _lm.predict(L, n, rd, rs, m)
        w = put_back(I, valid, (L, n, rd, rs, m), sigma, 0.5, 3.0)
    else:
        S = (L.d * L.mu[:, None]).astype(np.float32)
        pred = np.maximum(S @ (n * rd), 0)
        w = put_back(I, valid, (L, n, rd, None, None), sigma, 0.5, 3.0)
    ref = _reference(I, valid, pred, sigma, 0.5, 3.0)
    assert 0.05 < (~ref & valid).mean() < 0.2  # the test has dark observations
    # the Lambert prediction is rounded differently from S @ b: decisions may differ
    # only where the observation sits on a bound
    assert (w != ref).mean() <= (0 if lobe else 1e-4)
    if lobe:   # the caller's prediction (tsfit's refine round) gives the same weights
        np.testing.assert_array_equal(
            put_back(I, valid, (L, n, rd, rs, m), sigma, 0.5, 3.0, pred=pred), w)


def _grid(H=40, W=50, seed=1):
    rng = np.random.default_rng(seed)
    obj = rng.random((H, W)) > 0.1
    idx = np.flatnonzero(obj)
    fitted = rng.random(idx.size) > 0.05
    n = rng.normal(size=(3, idx.size))
    n[2] = np.abs(n[2]) + 1
    n = (n / np.linalg.norm(n, axis=0)).astype(np.float32)
    return _tsprop.Grid(idx, (H, W), fitted), n


def _mean_reference(grid, n):
    H, W = grid.shape
    full = np.zeros((3, H + 2, W + 2))
    fi = np.zeros((H, W), bool)
    fi.reshape(-1)[grid.idx[grid.fitted]] = True
    vals = np.zeros((3, H * W))
    vals[:, grid.idx[grid.fitted]] = n[:, grid.fitted]
    full[:, 1:-1, 1:-1] = vals.reshape(3, H, W)
    acc = sum(full[:, 1 + dy:H + 1 + dy, 1 + dx:W + 1 + dx]
              for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0))
    acc = acc.reshape(3, -1)[:, grid.idx]
    norm = np.linalg.norm(acc, axis=0)
    mean = acc / np.where(norm > 0, norm, 1)
    ang = np.arccos(np.clip((mean * n).sum(0), -1, 1))
    return np.where((norm > 0) & grid.fitted, ang, np.nan), mean


def test_neighbour_mean_and_near_match_numpy():
    grid, n = _grid()
    ang, mean = grid.disagreement(n)
    ref_ang, ref_mean = _mean_reference(grid, n)
    np.testing.assert_array_equal(np.isnan(ang), np.isnan(ref_ang))
    ok = ~np.isnan(ang)
    np.testing.assert_allclose(ang[ok], ref_ang[ok], atol=1e-5)
    np.testing.assert_allclose(mean[:, ok], ref_mean[:, ok], atol=1e-6)
    changed = np.zeros(grid.idx.size, bool)
    changed[::37] = True
    H, W = grid.shape
    img = np.zeros((H + 2, W + 2), bool)
    img.reshape(-1)[grid.flat[changed & grid.fitted]] = True
    hit = np.zeros((H, W), bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if (dy, dx) != (0, 0):
                hit |= img[1 + dy:H + 1 + dy, 1 + dx:W + 1 + dx]
    np.testing.assert_array_equal(grid.near(changed), hit.reshape(-1)[grid.idx] & grid.fitted)


def test_independent_of_thread_count():
    L, n, rd, rs, m, I, valid = _pixels(p=20000)
    sigma = np.full(L.k, 0.03, np.float32)
    grid, gn = _grid(H=150, W=140)
    before = numba.get_num_threads()
    out = []
    try:
        for t in sorted({1, numba.config.NUMBA_NUM_THREADS}):
            numba.set_num_threads(t)
            out.append((put_back(I, valid, (L, n, rd, rs, m), sigma, 0.5, 3.0),
                        *grid.disagreement(gn)))
    finally:
        numba.set_num_threads(before)
    for a, b in zip(out[0], out[-1]):
        np.testing.assert_array_equal(a, b)


def _median_loop(I, pred, w, lambert):
    """noise_sigma's numpy form: np.median of each image's kept |residuals|."""
    r = pred - I
    inl = w >= 0.5
    if lambert:
        inl &= r >= 0
    else:
        np.abs(r, out=r)
    sig = np.full(r.shape[0], np.nan)
    for i in range(r.shape[0]):
        ri = r[i][inl[i]]
        if ri.size:
            sig[i] = 1.4826 * np.median(ri)
    ok = np.isfinite(sig)
    fill = float(np.median(sig[ok])) if ok.any() else 0.0
    return np.where(ok, sig, fill).astype(np.float32)


@pytest.mark.parametrize("lambert", [True, False])
def test_noise_sigma_is_np_median_bit_for_bit(lambert):
    """The selection kernel picks exactly the values np.median averages: odd and even
    counts, ties (quantised data), one kept value, rows with none, a NaN kept, values
    spread over many octaves and values all in one bin."""
    from psbench.solve.methods.tsfit._start import noise_sigma

    rng = np.random.default_rng(3)
    for t in range(120):
        k, p = int(rng.integers(1, 12)), int(rng.integers(1, 2500))
        I = rng.random((k, p)).astype(np.float32)
        if t % 3 == 0:
            I = (np.round(I * 8) / 8).astype(np.float32)           # many ties
        scale = 10.0 ** rng.uniform(-6, 1, (k, p)) if t % 4 == 0 else 0.05
        pred = (I + rng.normal(size=I.shape) * scale).astype(np.float32)
        if t % 5 == 0:
            pred = 1.0 + rng.random(I.shape).astype(np.float32) * 1e-6   # one bin
            pred = pred.astype(np.float32)
        w = rng.random((k, p)) < rng.uniform(0.0005, 1.0)
        w[0, :] = w[0, :] if t % 7 else False                     # a row with none
        if t % 6 == 0:
            w[-1, :] = False
            w[-1, int(rng.integers(p))] = True                     # one kept value
        if t % 11 == 0:
            I[0, 0], w[0, 0] = np.nan, True                        # a NaN kept
        got = noise_sigma(I, pred, w, lambert=lambert)
        want = _median_loop(I, pred, w, lambert)
        np.testing.assert_array_equal(got.view(np.int32), want.view(np.int32),
                                      err_msg=f"case {t}")
