"""The compiled per-pixel passes of the solver (Eq. 3.1's completion, Eq. 3.19's weights)
against numpy formulations of the same steps."""
import cv2
import numba
import numpy as np
import pytest

from psbench.solve import _complete_kernel as ck
from psbench.solve.weighted import disk, weighted_masks


@pytest.mark.parametrize("k", [4, 16, 40])   # 40: beyond the insertion sort
def test_order_is_numpys_stable_argsort(k):
    rng = np.random.default_rng(k)
    r = np.round(rng.random((k, 3000)) * 4).astype(np.float32)  # many ties
    r[:, :5] = 0.0
    r[1, 7] = np.nan
    r[3, 8] = np.inf
    want = np.argsort(r, axis=0, kind="stable").astype(np.uint8)
    assert np.array_equal(ck.order(r, np.uint8), want)


def test_fill_and_counts_match_the_vectorised_rule():
    rng = np.random.default_rng(5)
    k, n = 8, 5000
    valid = rng.random((k, n)) > 0.8
    order = np.argsort(rng.random((k, n)), axis=0).astype(np.uint8)
    short, cnt = ck.short_columns(valid)
    assert np.array_equal(short, np.flatnonzero(valid.sum(axis=0) < 3))
    assert np.array_equal(cnt, valid.sum(axis=0)[short])
    want = valid.copy()
    for j in short:   # reference: add the best masked observations until three are used
        for i in order[:, j]:
            if want[:, j].sum() >= 3:
                break
            want[i, j] = True
    got = ck.fill(valid.copy(), short, cnt, order[:, short])
    assert np.array_equal(got, want)


def _weighted_ref(images, S, b, valid, sigma_min, dilate_radius=7, smooth_sigma=3.0, size=15):
    """Eq. 3.19 step by step (sigma^2 dilated, inverted, blurred), per light in numpy."""
    k, H, W = images.shape
    se = disk(min(dilate_radius, (size - 1) // 2), size)
    out = np.empty_like(images)
    smin = np.float32(sigma_min)
    S = np.asarray(S, np.float32)
    for i in range(k):
        L = (b.reshape(-1, 3) @ S[i]).reshape(H, W)
        r = np.abs(images[i] - L)
        sig = np.where(~valid[i] & (r >= smin), r / smin, np.float32(1.0)).astype(np.float32)
        var = cv2.dilate(sig * sig, se, borderType=cv2.BORDER_REPLICATE) if dilate_radius else sig * sig
        w = np.float32(1.0) / var
        out[i] = cv2.GaussianBlur(w, (size, size), smooth_sigma,
                                  borderType=cv2.BORDER_REPLICATE) if smooth_sigma else w
    return out


@pytest.mark.parametrize("radius, sigma", [(7, 3.0), (0, 0.0), (3, 0.0), (0, 2.0)])
def test_weighted_masks_match_the_stepwise_formulation(radius, sigma):
    rng = np.random.default_rng(radius)
    k, H, W = 6, 48, 52
    b = rng.normal(size=(H, W, 3)).astype(np.float32)
    S = rng.normal(size=(k, 3))
    images = np.einsum("ij,hwj->ihw", S, b).astype(np.float32)
    images += rng.normal(scale=0.01, size=images.shape).astype(np.float32)
    valid = rng.random((k, H, W)) > 0.02   # a few masked observations, half of them outliers
    images[~valid & (rng.random((k, H, W)) > 0.5)] += 3.0
    want = _weighted_ref(images, S, b, valid, 0.05, radius, sigma)
    got = weighted_masks(images, S, b, valid, sigma_min=0.05, dilate_radius=radius,
                         smooth_sigma=sigma, kernel_size=15)
    # the Lambert image is a 3-term float32 sum: the two may round it differently
    np.testing.assert_allclose(got, want, rtol=1e-5, atol=0)
    assert got.min() < 0.9 and got.max() > 0.99  # masked and trusted observations both occur


def test_weighted_masks_do_not_depend_on_numba_threads():
    rng = np.random.default_rng(9)
    k, H, W = 5, 40, 30
    args = (rng.random((k, H, W), dtype=np.float32), rng.normal(size=(k, 3)),
            rng.normal(size=(H, W, 3)).astype(np.float32), rng.random((k, H, W)) > 0.4)
    n0 = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = weighted_masks(*args, sigma_min=0.05)
        numba.set_num_threads(n0)
        many = weighted_masks(*args, sigma_min=0.05)
    finally:
        numba.set_num_threads(n0)
    assert np.array_equal(one, many)


def test_mask_kernels_match_the_matrix_products():
    from psbench.solve.masks import _shared

    rng = np.random.default_rng(11)
    k, n = 16, 4000
    S = rng.normal(size=(k, 3)).astype(np.float32)
    b = rng.normal(size=(n, 3)).astype(np.float32)
    images = rng.random((k, n), dtype=np.float32)

    class Ctx:
        cache = {}
        S32 = S

    r = _shared.lambert_residual(Ctx, images, b)
    np.testing.assert_allclose(r, images - S @ b.T, rtol=0, atol=1e-5)
    nrm = b / np.linalg.norm(b, axis=1, keepdims=True)
    d = rng.normal(size=(k, 3))
    d[:, 2] = np.abs(d[:, 2])
    got = _shared.reflection_valid(nrm, d, 25.0)
    cos = (_shared.bisectors(d).astype(np.float32) @ nrm.T)
    want = cos <= np.float32(np.cos(np.radians(25.0)))
    sure = np.abs(cos - np.float32(np.cos(np.radians(25.0)))) > 1e-6  # off the threshold
    assert got.shape == (k, n) and np.array_equal(got[sure], want[sure])
