"""Pictures of a solve (psbench.io.write_outputs and the picture helpers): every file is
written, decodes, and shows what it claims (not black, the right colour code, the right
mesh)."""
import cv2
import numpy as np
import pytest

from psbench import io
from psbench._shared.checks import PsbenchError
from psbench.io import _pictures as P
from psbench.io._relief import height_picture
from psbench.lights import layout


def _rgb(path):
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert img is not None, path
    return img[..., ::-1] if img.ndim == 3 else img


@pytest.fixture(scope="module")
def solved():
    import psbench as ps

    s = ps.make_surface("spheres", size=48)
    lay = layout("45x8")
    sc = ps.render(s, lay, model="ts", noise=0.02, seed=0)
    res = ps.solve(sc.images, lay, mask="Th", object_mask=s.object_mask)
    return s, sc, res


def test_write_outputs_every_picture(tmp_path, solved):
    s, sc, res = solved
    files = io.write_outputs(tmp_path, res, object_mask=s.object_mask, images=sc.images,
                             truth_normals=s.normals, true_outliers=sc.highlight | sc.shadow,
                             per_image=False)
    want = {"normals.png", "albedo.png", "input.png", "truth.png", "error.png", "ne_map.png",
            "mask.png", "height.png", "object_mask.png", "mesh.ply", "mesh.obj",
            "normals.npz", "albedo.npz", "ne.npz", "valid.npz", "height.npz"}
    assert want <= set(files)
    assert not (tmp_path / "valid").exists()                      # per_image=False
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no temp files
    m = s.object_mask
    # normal map in DiLiGenT's code (n + 1) / 2, 8-bit
    png = _rgb(tmp_path / "normals.png")
    assert np.abs(png[m] / 255.0 - (res.normals[m] + 1) / 2).max() <= 0.6 / 255
    truth = _rgb(tmp_path / "truth.png")
    assert np.abs(truth[m] / 255.0 - (s.normals[m] + 1) / 2).max() <= 0.6 / 255
    # NE data and its colour map: white outside the object, coloured inside
    ne = np.load(tmp_path / "ne.npz")["ne"]
    assert np.isnan(ne[~m]).all() and np.isfinite(ne[m]).all()
    nem = _rgb(tmp_path / "ne_map.png")
    assert (nem[~m] == 255).all()
    assert len(np.unique(nem[m].reshape(-1, 3), axis=0)) > 20
    err = _rgb(tmp_path / "error.png")                           # map + colour bar + title
    assert err.shape[1] > nem.shape[1] + 30 and err.shape[0] > nem.shape[0]
    # the shaded heights are a picture, not a blank canvas
    h = _rgb(tmp_path / "height.png")
    assert h.std() > 10 and h.shape[0] > 40
    # overlay of the mask: coloured pixels where observations were excluded
    ov = _rgb(tmp_path / "mask.png")
    col = (ov.max(axis=-1).astype(int) - ov.min(axis=-1)) > 60
    assert col.mean() > 0.01


def test_albedo_scaled_by_robust_percentile(tmp_path):
    """One specular spot (max 4.12, 99th percentile 0.18) must not make the picture black."""
    class R:
        pass
    rng = np.random.default_rng(0)
    r = R()
    r.normals = np.dstack([np.zeros((64, 64)), np.zeros((64, 64)), np.ones((64, 64))])
    r.albedo = rng.uniform(0.05, 0.18, (64, 64)).astype(np.float32)
    r.albedo[10:12, 10:12] = 4.12
    io.write_outputs(tmp_path, r, height=False, arrays=False)
    a = _rgb(tmp_path / "albedo.png")
    assert a.dtype == np.uint8
    assert np.percentile(a, 99) >= 250          # the 99th percentile maps to white
    assert np.median(a) > 100                   # and the bulk of the object is visible


def test_meshes_ply_and_obj_agree(tmp_path):
    h = np.arange(12, dtype=float).reshape(3, 4)
    m = np.ones((3, 4), bool)
    m[0, 0] = False
    nv, nf = io.write_obj(tmp_path / "m.obj", h, object_mask=m)
    nv2, nf2 = io.write_ply(tmp_path / "m.ply", h, object_mask=m, binary=False)
    assert nv == nv2 == 11 and (nf, nf2) == (5, 10)       # OBJ: one quad per two triangles
    lines = (tmp_path / "m.obj").read_text().splitlines()
    v = np.array([[float(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("v ")])
    f = np.array([[int(x) for x in ln.split()[1:]] for ln in lines if ln.startswith("f ")])
    assert v.shape == (11, 3) and f.shape == (5, 4) and f.min() == 1 and f.max() == 11
    assert np.allclose(v[0], [-0.5, 1.0, 1.0])
    for i, j, k in ((0, 1, 2), (0, 2, 3)):            # both halves counter-clockwise from +z
        a, b, c = v[f[:, i] - 1], v[f[:, j] - 1], v[f[:, k] - 1]
        assert (np.cross(b - a, c - a)[:, 2] > 0).all()


def test_encode_normals_codes():
    n = np.array([[[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]]])
    assert np.allclose(io.encode_normals(n)[0, 0], [0.5, 0.5, 1.0])
    assert np.allclose(io.encode_normals(n, code="thesis")[0, 1], [0.8, 0.5, 0.8])
    with pytest.raises(PsbenchError, match="code"):
        io.encode_normals(n, code="rgb")


def test_height_picture_hides_what_is_behind():
    """A tall wall in front hides a low plateau behind it (exact for height maps)."""
    h = np.zeros((40, 40), np.float32)
    h[30:34, :] = 30.0                                    # a wall near the viewer
    front = height_picture(h, elevation=20, azimuth=0)
    flat = height_picture(np.zeros_like(h), elevation=20, azimuth=0)
    assert front.shape[0] > flat.shape[0]                 # the wall rises above the plane
    assert (front != 245).any(axis=-1).mean() > 0.3
    # nothing for an empty mask, no error
    assert height_picture(h, np.zeros_like(h, bool)).shape == (64, 64, 3)


def test_colour_bar_and_montage_sizes():
    bar = P.color_bar(200, 0, 20, label="NE (deg)", over=True)
    assert bar.shape[0] == 200 and bar.dtype == np.uint8
    tiles = [np.full((30, 40, 3), i * 20, np.uint8) for i in range(7)]
    grid = P.montage(tiles, ncols=3, labels=list("abcdefg"))
    assert grid.shape[1] == 3 * 40 + 2 * 4 and grid.shape[0] > 3 * 30


def test_colour_bar_ticks_are_round():
    from psbench.io._pictures import nice_ticks

    assert list(nice_ticks(0.0, 0.00318386)) == [0.0, 0.001, 0.002, 0.003]
    assert list(nice_ticks(0.0, 1.0)) == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert all(str(t) != "-0.0" for t in nice_ticks(-180.0, 3.0))


def _ink_rows(rgb):
    """Rows of ``rgb`` holding dark text ink."""
    return np.nonzero((rgb.max(axis=-1) < 80).any(axis=1))[0]


def test_text_grows_with_the_picture():
    """A 2048 px NE map's title and colour-bar labels are as large, relative to the
    picture, as a 256 px one's would be at 2048 / 45 px: no tiny text on big pictures."""
    small, big = (P.error_picture(np.full((n, n), 5.0, np.float32), title="mean NE 5.00 deg")
                  for n in (256, 2048))
    band = lambda pic, n: pic.shape[0] - n                  # noqa: E731 - the title band
    assert band(small, 256) >= 16 and band(big, 2048) >= 2.5 * band(small, 256)
    assert P.text_px(256) == 14 and P.text_px(2048) >= 45
    bar_small, bar_big = (P.color_bar(n, 0, 20, label="NE (deg)", size=P.text_px(n))
                          for n in (256, 2048))
    assert bar_big.shape[1] >= 2.5 * bar_small.shape[1]      # wider labels, wider bar


def test_height_render_of_a_large_map_keeps_its_detail_and_a_micrometre_bar():
    """A 720 px map is rendered at its own resolution (not shrunk to a few hundred px:
    fine marks stay visible); with a pixel size a scale bar of a round length in um is
    drawn whose length matches that size."""
    n = 720
    y, x = np.mgrid[:n, :n].astype(np.float32)
    h = 0.5 * np.sin(x / 3.0)                                # marks 19 px apart
    plain = height_picture(h, elevation=90, azimuth=0)
    assert plain.shape[1] >= n
    assert height_picture(h[:128, :128]).shape[1] >= 256     # small maps are enlarged
    px = 4.9                                                 # um per pixel
    barred = height_picture(h, elevation=90, azimuth=0, pixel_size=px)
    diff = (barred != plain).any(axis=-1)
    rows = np.nonzero(diff.sum(axis=1) > 100)[0]             # the bar's thick line
    assert rows.size
    um = diff[rows[0]].sum() * px                            # one render px per map px
    assert any(abs(um - v) / v < 0.02 for v in (500, 1000, 2000)), um
