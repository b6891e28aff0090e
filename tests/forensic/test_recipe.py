"""psbench's forensic recipe and the breechface study's per-scan and per-pair pieces."""
import numpy as np
import pandas as pd
import pytest

from psbench._shared.checks import PsbenchError
from psbench.forensic import breechface as bf
from psbench.forensic import reconstruct_heights
from psbench.forensic.recipe import clipped_fractions

PIXEL = 6.25


def _scan(seed, size=96):
    """A flat, finely marked disc in µm, like a breech face (NaN outside)."""
    import cv2
    rng = np.random.default_rng(seed)
    z = cv2.GaussianBlur(rng.standard_normal((size, size)).astype(np.float32), (0, 0), 2.0)
    yy, xx = np.mgrid[:size, :size] - (size - 1) / 2
    v = np.hypot(yy, xx) < 0.45 * size
    return np.where(v, 2.0 * z, np.nan).astype(np.float32), v


def test_recipe_leaves_out_overexposed_images_and_tracks_the_scan():
    z, v = _scan(0)
    acq = bf.render_scan(z, v, pixel_size=PIXEL, finish="brass")
    images = acq.images.copy()
    # overexpose the 31 deg ring, as frame-metered exposure does on real scans
    images[:8] = np.clip(images[:8].astype(np.float32) * 4, 0, 255).astype(np.uint8)
    frac = clipped_fractions(images, v)
    assert frac[:8].min() > 0.05 > frac[8:].max()
    h = reconstruct_heights(images, acq.lights, object_mask=v, pixel_size=PIXEL)
    assert h.shape == z.shape and h.dtype == np.float32
    f = bf.bandpass(h, v, pixel_size=PIXEL, short=16, long=500)
    r = bf.bandpass(np.where(v, z, 0), v, pixel_size=PIXEL, short=16, long=500)
    assert np.corrcoef(f[v], r[v])[0, 1] > 0.9
    # amplitude within 50 % of the scan's (least squares on all lights is biased)
    assert 0.5 < float(np.std(f[v]) / np.std(r[v])) < 1.5


def test_recipe_bad_input():
    z, v = _scan(1, 48)
    acq = bf.render_scan(z, v, pixel_size=PIXEL)
    with pytest.raises(PsbenchError, match="pixel_size"):
        reconstruct_heights(acq.images, acq.lights, object_mask=v, pixel_size=-1)
    with pytest.raises(PsbenchError, match="lights"):
        reconstruct_heights(acq.images, np.ones((3, 3)), object_mask=v, pixel_size=PIXEL)
    with pytest.raises(PsbenchError, match="object_mask"):
        reconstruct_heights(acq.images, acq.lights, object_mask=v[:5], pixel_size=PIXEL)
    with pytest.raises(PsbenchError, match="max_clipped"):
        reconstruct_heights(acq.images, acq.lights, object_mask=v, pixel_size=PIXEL,
                            max_clipped=2)


def test_equal_error_rate():
    assert bf.equal_error_rate([3, 4, 5], [0, 1, 2]) == 0.0
    assert bf.equal_error_rate([0, 1], [0, 1]) == pytest.approx(0.5)


def test_study_pieces_on_two_guns():
    maps, valid, guns, per = {}, {}, {}, []
    for i, (gun, seed) in enumerate([("1", 0), ("1", 0), ("2", 5)]):
        z, v = _scan(seed, 128)
        m, rows = bf.reconstruct_scan(z, v, pixel_size=PIXEL, methods=("None",),
                                      integrators=("poisson",), seed=i,
                                      recipe=reconstruct_heights)
        assert set(m) == {(bf.SCAN, "-"), ("None", "poisson"), ("recipe", "-")}
        name = f"s{i}"
        maps[name], valid[name], guns[name] = m[("recipe", "-")], v, gun
        per += [{**r, "finish": "brass"} for r in rows]
    sc = bf.score_pairs(maps, valid, guns, pixel_size=PIXEL, cells=(4, 4))
    sc["finish"], sc["method"], sc["integrator"] = "brass", "recipe", "-"
    assert sc.same_gun.sum() == 1 and len(sc) == 3
    same = sc[sc.same_gun]
    assert int(same["count"].iloc[0]) > int(sc[~sc.same_gun]["count"].max())
    table = bf.summarise(sc, pd.DataFrame(per))
    assert table.loc[0, "auc_cmc"] == 1.0 and table.loc[0, "separation_cmc"] > 0
