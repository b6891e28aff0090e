"""Bilateral normal integration (psbench._bilateral)."""
import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError
from psbench.integrate.bilateral import bilateral_integrate


def _normals(p, q):
    n = np.stack([-p, -q, np.ones_like(p)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _grid(H, W):
    x = np.arange(W) - (W - 1) / 2
    y = (H - 1) / 2 - np.arange(H)[:, None]
    return np.broadcast_to(x, (H, W)), np.broadcast_to(y, (H, W))


def test_plane_is_exact_and_datum():
    x, y = _grid(40, 50)
    z = 0.3 * x - 0.2 * y
    h = bilateral_integrate(_normals(np.full_like(x, 0.3), np.full_like(x, -0.2)))
    np.testing.assert_allclose(h - h.mean(), z - z.mean(), atol=1e-3)
    assert h.min() == pytest.approx(0.0, abs=1e-6)
    hm = bilateral_integrate(_normals(np.full_like(x, 0.3), np.full_like(x, -0.2)), datum="mean")
    assert abs(hm.mean()) < 1e-6


def test_smooth_surface_as_good_as_poisson():
    s = ps.make_surface("semisphere_disc", size=96)
    h = bilateral_integrate(s.normals, object_mask=s.object_mask)
    hp = ps.integrate(s.normals, object_mask=s.object_mask)
    inner = s.object_mask & (s.zenith < 60)

    def err(e):
        d = (e - s.height)[inner]
        return np.abs(d - np.median(d)).mean()

    assert err(h) < 0.05 and err(h) <= 1.2 * err(hp)
    assert (h[~s.object_mask] == 0).all()


def test_keeps_a_discontinuity_poisson_smears():
    """Right half tilted, left half flat, a height jump between them that shrinks to 0:
    exact normals on both sides carry no curl-free path across the jump. Poisson
    spreads the inconsistency over both halves; the bilateral weights cut it."""
    x, y = _grid(80, 80)
    s = 0.8
    z = np.where(x > 0, s * (y + 40), 0.0)
    n = _normals(np.zeros_like(x), np.where(x > 0, s, 0.0))
    hb, info = bilateral_integrate(n, return_info=True)
    hp = ps.integrate(n)
    for side in (x > 0, x < 0):
        eb = (hb - z)[side]
        ep = (hp - z)[side]
        assert np.abs(eb - np.median(eb)).mean() < 0.2 * np.abs(ep - np.median(ep)).mean()
    # every row where the jump is large is cut within a pixel of it (weight ~0 or ~1)
    near = np.abs(x[0]) < 2
    rows = y[:, 0] > 10
    assert (np.abs(info["wu"][rows][:, near] - 0.5).max(axis=1) > 0.45).all()
    assert info["iterations"] >= 2 and info["energy"][-1] <= info["energy"][0]


def test_components_and_empty_mask():
    x, y = _grid(30, 30)
    n = _normals(np.full_like(x, 0.1), np.zeros_like(x))
    m = np.zeros((30, 30), bool)
    m[2:10, 2:10] = m[15:28, 15:28] = True
    h = bilateral_integrate(n, object_mask=m)
    assert h[2:10, 2:10].min() == pytest.approx(0, abs=1e-6)
    assert h[15:28, 15:28].min() == pytest.approx(0, abs=1e-6)
    assert (bilateral_integrate(n, object_mask=np.zeros((30, 30), bool)) == 0).all()


@pytest.mark.parametrize("kwargs, word", [
    (dict(k=0), "k"), (dict(max_iter=0), "max_iter"), (dict(tol=-1), "tol"),
    (dict(datum="max"), "datum"), (dict(cg_maxiter=1.5), "cg_maxiter"),
])
def test_bad_input(kwargs, word):
    n = _normals(np.zeros((8, 8)), np.zeros((8, 8)))
    with pytest.raises(PsbenchError, match=word):
        bilateral_integrate(n, **kwargs)
    with pytest.raises(PsbenchError, match="normals"):
        bilateral_integrate(np.zeros((8, 8)))
    bad = n.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(PsbenchError, match="NaN"):
        bilateral_integrate(bad)
