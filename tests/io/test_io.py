"""psbench.io: images, DiLiGenT-layout folders, outputs."""
from __future__ import annotations

import json
import struct

import cv2
import numpy as np
import pytest

from psbench import PsbenchError
from psbench import io
from psbench.lights import layout


def _quantized(k=6, H=12, W=10, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.integers(0, 65536, size=(k, H, W)).astype(np.uint16)
    return (q.astype(np.float32) / np.float32(65535)), q


# --------------------------------------------------------------------------- images
def test_read_8_16_bit_and_explicit_12_bit(tmp_path):
    a8 = np.array([[0, 128, 255]], np.uint8)
    a16 = np.array([[0, 4095, 65535]], np.uint16)
    cv2.imwrite(str(tmp_path / "a.png"), a8)
    cv2.imwrite(str(tmp_path / "b.png"), a16)
    cv2.imwrite(str(tmp_path / "c.tif"), a16)
    assert np.allclose(io.read_image(tmp_path / "a.png"), a8 / 255.0)
    assert np.allclose(io.read_image(tmp_path / "b.png"), a16 / 65535.0)
    assert np.allclose(io.read_image(tmp_path / "c.tif"), a16 / 65535.0)
    # 12-bit data in a 16-bit container: only when told
    assert io.read_image(tmp_path / "b.png", bits=12)[0, 1] == pytest.approx(1.0)
    assert io.read_image(tmp_path / "b.png").dtype == np.float32
    assert io.read_image(tmp_path / "b.png", raw=True).dtype == np.uint16


def test_colour_is_bt601_luma(tmp_path):
    rgb = np.zeros((2, 2, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 200, 100, 50
    cv2.imwrite(str(tmp_path / "c.png"), rgb[..., ::-1])  # OpenCV writes BGR
    got = io.read_image(tmp_path / "c.png")
    assert np.allclose(got, (0.299 * 200 + 0.587 * 100 + 0.114 * 50) / 255, atol=1e-6)


def test_write_image_roundtrip_bits(tmp_path):
    img = np.linspace(0, 1, 20, dtype=np.float32).reshape(4, 5)
    for bits in (8, 12, 16):
        io.write_image(tmp_path / f"x{bits}.png", img, bits=bits)
        raw = io.read_image(tmp_path / f"x{bits}.png", raw=True)
        assert raw.dtype == (np.uint8 if bits == 8 else np.uint16)
        assert raw.max() == 2 ** bits - 1
        back = io.read_image(tmp_path / f"x{bits}.png", bits=None if bits != 12 else 12)
        assert np.abs(back - img).max() <= 0.5 / (2 ** bits - 1) + 1e-7


def test_read_images_errors(tmp_path):
    io.write_image(tmp_path / "a.png", np.zeros((4, 5)), bits=16)
    io.write_image(tmp_path / "b.png", np.zeros((5, 5)), bits=16)
    io.write_image(tmp_path / "c.png", np.zeros((4, 5)), bits=8)
    (tmp_path / "bad.png").write_bytes(b"not a png")
    with pytest.raises(PsbenchError, match="does not exist"):
        io.read_images([tmp_path / "a.png", tmp_path / "missing.png"])
    with pytest.raises(PsbenchError, match="differ in size"):
        io.read_images([tmp_path / "a.png", tmp_path / "b.png"])
    with pytest.raises(PsbenchError, match="bit depth"):
        io.read_images([tmp_path / "a.png", tmp_path / "c.png"])
    with pytest.raises(PsbenchError, match="could not be decoded"):
        io.read_images([tmp_path / "bad.png"])
    with pytest.raises(PsbenchError, match="empty"):
        io.read_images([])


# --------------------------------------------------------------------------- datasets
def test_dataset_roundtrip_exact(tmp_path):
    imgs, q = _quantized()
    lay = layout("30x3+60x3")
    mask = np.zeros(imgs.shape[1:], bool)
    mask[2:9, 1:8] = True
    rng = np.random.default_rng(1)
    nrm = rng.normal(size=imgs.shape[1:] + (3,)).astype(np.float32)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    io.write_dataset(tmp_path / "ds", imgs, lay, object_mask=mask, normals=nrm,
                     meta={"note": "x"})
    ds = io.read_dataset(tmp_path / "ds")
    assert np.array_equal(ds.images, imgs)  # exact on 16-bit-quantized data
    assert np.array_equal(io.read_image(tmp_path / "ds" / "001.png", raw=True), q[0])
    assert np.allclose(ds.lights.directions, lay.directions, atol=1e-12)
    assert np.array_equal(ds.lights.ring, lay.ring)
    assert ds.lights.n_rings == 2
    assert np.array_equal(ds.object_mask, mask)
    assert np.array_equal(ds.normals, nrm)
    assert ds.names == [f"{i:03d}.png" for i in range(1, 7)]
    assert ds.meta["note"] == "x" and ds.meta["calibrated"] is False
    # a second write of what was read gives identical files
    io.write_dataset(tmp_path / "ds2", ds.images, ds.lights, object_mask=ds.object_mask, normals=ds.normals,
                     meta={"note": "x"})
    for f in ["001.png", "006.png", "light_directions.txt", "mask.png", "normals.npy"]:
        assert (tmp_path / "ds" / f).read_bytes() == (tmp_path / "ds2" / f).read_bytes()


def test_positions_roundtrip(tmp_path):
    imgs, _ = _quantized(k=4)
    lay = layout("45x4")
    lay = layout(lay.directions, positions=lay.directions * 500.0, ring=lay.ring)
    io.write_dataset(tmp_path / "ds", imgs, lay)
    ds = io.read_dataset(tmp_path / "ds")
    assert np.allclose(ds.lights.positions, lay.positions)


def test_write_dataset_is_atomic(tmp_path):
    imgs, _ = _quantized(k=4)
    with pytest.raises(PsbenchError):
        io.write_dataset(tmp_path / "ds", imgs, layout("45x3"))  # 3 lights for 4 images
    with pytest.raises(RuntimeError):
        io.write_dataset(tmp_path / "ds", imgs, layout("45x4"),
                         extra={"boom": lambda d: (_ for _ in ()).throw(RuntimeError("x"))})
    assert list(tmp_path.iterdir()) == []
    io.write_dataset(tmp_path / "ds", imgs, layout("45x4"))
    with pytest.raises(PsbenchError, match="already exists"):
        io.write_dataset(tmp_path / "ds", imgs, layout("45x4"))


def test_light_intensities_divide(tmp_path):
    imgs, _ = _quantized(k=4)
    io.write_dataset(tmp_path / "ds", imgs, layout("45x4"))
    (tmp_path / "ds" / "light_intensities.txt").write_text("2\n4\n1\n0.5\n")
    ds = io.read_dataset(tmp_path / "ds")
    assert np.allclose(ds.images, imgs / np.array([2, 4, 1, 0.5], np.float32)[:, None, None])
    rgb = np.array([[1, 2, 3]] * 4, float)
    (tmp_path / "ds" / "light_intensities.txt").write_text("\n".join("1 2 3" for _ in range(4)))
    ds = io.read_dataset(tmp_path / "ds")  # gray images: divided by the luma of the RGB intensity
    assert np.allclose(ds.images, imgs / np.float32(rgb[0] @ io.LUMA), rtol=1e-6)


def _folder(tmp_path, k=4):
    imgs, _ = _quantized(k=k)
    p = tmp_path / "ds"
    io.write_dataset(p, imgs, layout("45x4"), object_mask=np.ones(imgs.shape[1:], bool))
    return p


def test_count_mismatch_names_file_and_counts(tmp_path):
    p = _folder(tmp_path)
    lines = (p / "light_directions.txt").read_text().splitlines()
    (p / "light_directions.txt").write_text("\n".join(lines[:3]) + "\n")
    with pytest.raises(PsbenchError, match=r"light_directions.txt: 3 light directions but 4 images"):
        io.read_dataset(p)


def test_missing_image(tmp_path):
    p = _folder(tmp_path)
    (p / "003.png").unlink()
    with pytest.raises(PsbenchError, match="003.png.*does not exist"):
        io.read_dataset(p)


def test_non_unit_directions_warn_or_fail(tmp_path):
    p = _folder(tmp_path)
    d = np.loadtxt(p / "light_directions.txt")
    np.savetxt(p / "light_directions.txt", d * np.array([[1.01], [1], [1], [1]]))
    with pytest.warns(io.PsbenchWarning, match=r"rows \[1\] are not unit"):
        ds = io.read_dataset(p)
    assert np.allclose(np.linalg.norm(ds.lights.directions, axis=1), 1)
    np.savetxt(p / "light_directions.txt", d * np.array([[1], [2], [1], [1]]))
    with pytest.raises(PsbenchError, match=r"rows \[2\] are not unit"):
        io.read_dataset(p)


def test_directions_away_from_camera(tmp_path):
    p = _folder(tmp_path)
    d = np.loadtxt(p / "light_directions.txt")
    d[[1, 3], 2] *= -1
    np.savetxt(p / "light_directions.txt", d)
    with pytest.raises(PsbenchError, match=r"light_directions.txt: rows \[2, 4\] point away"):
        io.read_dataset(p)


def test_wrong_mask_size(tmp_path):
    p = _folder(tmp_path)
    io.write_image(p / "mask.png", np.ones((3, 3), np.uint8) * 255)
    with pytest.raises(PsbenchError, match="mask.png: mask is 3x3"):
        io.read_dataset(p)


def test_missing_folder_and_directions(tmp_path):
    with pytest.raises(PsbenchError, match="does not exist"):
        io.read_dataset(tmp_path / "nope")
    p = _folder(tmp_path)
    (p / "light_directions.txt").unlink()
    with pytest.raises(PsbenchError, match="light_directions.txt"):
        io.read_dataset(p)


def test_size_mismatch_in_folder(tmp_path):
    p = _folder(tmp_path)
    io.write_image(p / "002.png", np.zeros((5, 5)), bits=16)
    with pytest.raises(PsbenchError, match="differ in size"):
        io.read_dataset(p)


def test_twelve_bit_from_meta(tmp_path):
    imgs = np.round(np.random.default_rng(0).uniform(0, 1, (4, 6, 6)) * 4095) / 4095
    io.write_dataset(tmp_path / "ds", imgs.astype(np.float32), layout("45x4"), bits=12)
    assert json.loads((tmp_path / "ds" / "psbench.json").read_text())["bits"] == 12
    assert io.read_image(tmp_path / "ds" / "001.png", raw=True).max() <= 4095
    ds = io.read_dataset(tmp_path / "ds")
    assert np.allclose(ds.images, imgs, atol=1e-6)


# --------------------------------------------------------------------------- outputs
class _Res:
    pass


def test_write_outputs(tmp_path):
    from psbench.surfaces import make_surface
    s = make_surface("semisphere_disc", size=24)
    r = _Res()
    r.normals, r.albedo = s.normals, np.where(s.object_mask, 0.5, 0).astype(np.float32)
    r.height = s.height
    r.valid = np.ones((3, 24, 24), bool)
    r.weights = np.full((3, 24, 24), 0.5, np.float32)
    files = io.write_outputs(tmp_path / "out", r, object_mask=s.object_mask)
    for f in ("normals.npz", "normals.png", "albedo.npz", "albedo.png", "height.npz", "mesh.ply",
              "valid.npz", "valid/001.png", "weights/003.png"):
        assert (tmp_path / "out" / f).is_file(), f
    assert "mesh.ply" in files
    png = cv2.imread(str(tmp_path / "out" / "normals.png"), cv2.IMREAD_UNCHANGED)[..., ::-1]
    assert png.dtype == np.uint8
    n = s.normals[12, 18]
    assert np.allclose(png[12, 18] / 255, (n + 1) / 2, atol=0.6 / 255)   # DiLiGenT's code
    assert png[0, 0].sum() == 0  # outside the mask


def test_ply_grid_triangulation(tmp_path):
    h = np.arange(12, dtype=float).reshape(3, 4)
    m = np.ones((3, 4), bool)
    m[0, 0] = False
    nv, nf = io.write_ply(tmp_path / "m.ply", h, object_mask=m, binary=False)
    assert nv == 11 and nf == 2 * (2 * 3 - 1)
    txt = (tmp_path / "m.ply").read_text().splitlines()
    end = txt.index("end_header")
    verts = np.array([list(map(float, ln.split())) for ln in txt[end + 1:end + 1 + nv]])
    # x right, y up: vertex of pixel (row 0, col 1) sits at x = 1 - 1.5, y = +1
    assert np.allclose(verts[0], [-0.5, 1.0, 1.0])
    faces = np.array([list(map(int, ln.split())) for ln in txt[end + 1 + nv:]])
    a, b, c = (verts[faces[:, j + 1]] for j in range(3))
    nz = np.cross(b - a, c - a)[:, 2]
    assert (nz > 0).all()  # counter-clockwise seen from +z
    nv2, nf2 = io.write_ply(tmp_path / "b.ply", h, object_mask=m, binary=True)
    data = (tmp_path / "b.ply").read_bytes()
    body = data[data.index(b"end_header\n") + 11:]
    assert len(body) == nv2 * 12 + nf2 * 13
    assert struct.unpack("<3f", body[:12]) == pytest.approx((-0.5, 1.0, 1.0))


def test_normal_gt_mat_and_colour_dataset(tmp_path):
    import scipy.io as sio
    p = tmp_path / "obj"
    p.mkdir()
    k, H, W = 4, 6, 5
    rng = np.random.default_rng(2)
    rgb = rng.integers(1000, 60000, size=(k, H, W, 3)).astype(np.uint16)
    names = [f"{i + 1:03d}.png" for i in range(k)]
    for n, img in zip(names, rgb):
        cv2.imwrite(str(p / n), img[..., ::-1])
    (p / "filenames.txt").write_text("\n".join(names) + "\n")
    np.savetxt(p / "light_directions.txt", layout("40x4").directions)
    inten = rng.uniform(0.5, 2.0, (k, 3))
    np.savetxt(p / "light_intensities.txt", inten)
    gt = np.zeros((H, W, 3))
    gt[..., 2] = 1
    sio.savemat(p / "Normal_gt.mat", {"Normal_gt": gt})
    ds = io.read_dataset(p)
    # each channel divided by its own intensity, then BT.601 luma
    want = ((rgb / 65535.0) / inten[:, None, None, :]) @ io.LUMA
    assert np.allclose(ds.images, want, rtol=1e-5)
    assert ds.normals.shape == (H, W, 3) and ds.object_mask.all()
    assert ds.meta["format"] == "diligent"
    sio.savemat(p / "Normal_gt.mat", {"N": gt})
    with pytest.raises(PsbenchError, match="no key 'Normal_gt'"):
        io.read_dataset(p)


def test_write_outputs_from_solve_and_wps(tmp_path):
    from psbench.render import render
    from psbench.solve import solve
    from psbench.surfaces import make_surface
    s = make_surface("spheres", size=32)
    lay = layout("30x4+60x4")
    sc = render(s, lay, model="lambert")
    res = solve(sc.images, lay, mask="Th", object_mask=s.object_mask, want_height=True)
    io.write_outputs(tmp_path / "ps", res, object_mask=s.object_mask)
    assert np.array_equal(np.load(tmp_path / "ps" / "normals.npz")["normals"], res.normals)
    assert len(list((tmp_path / "ps" / "valid").glob("*.png"))) == 8
    w = solve(sc.images, lay, method="wps", object_mask=s.object_mask)
    io.write_outputs(tmp_path / "wps", w, object_mask=s.object_mask)
    assert len(list((tmp_path / "wps" / "ring_weights").glob("*.png"))) == 2  # one per ring
    assert (tmp_path / "wps" / "mesh.ply").is_file()  # height integrated when absent


def test_calibrated_pixel_size_reaches_the_dataset(tmp_path):
    """A capture whose calibration measured its pixel size (mm) reports it in um."""
    from psbench.calibrate import Calibration
    from psbench.render import render
    from psbench.surfaces import make_surface

    s = make_surface("semisphere", size=16)
    lay = layout("45x4")
    io.write_dataset(tmp_path / "cap", render(s, lay, model="lambert").images, lay)
    assert "pixel_size_um" not in io.read_dataset(tmp_path / "cap").meta
    io.save_calibration(Calibration(pixel_size=0.0049), tmp_path / "cap" / "calibration")
    ds = io.read_dataset(tmp_path / "cap")
    assert ds.meta["calibrated"] and ds.meta["pixel_size_um"] == pytest.approx(4.9)
