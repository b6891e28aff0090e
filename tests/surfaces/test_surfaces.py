import cv2
import numpy as np
import pytest

import psbench as ps
from psbench.surfaces import SOMBRERO_LAMBDA, normals_from_height, pixel_grid


@pytest.mark.parametrize("size", [64, 128])
@pytest.mark.parametrize("name", ps.SURFACES)
def test_every_surface_is_well_formed_and_deterministic(name, size):
    if name.startswith("cartridge"):
        size *= 4                     # its marks need >= 251 px over the 10 mm field of view
    s = ps.make_surface(name, size=size)
    assert s.height.shape == (size, size) and s.height.dtype == np.float32
    assert s.object_mask.shape == (size, size) and s.object_mask.dtype == bool
    assert s.object_mask.any()
    assert s.normals.shape == (size, size, 3) and s.normals.dtype == np.float32
    assert np.isfinite(s.height).all() and np.isfinite(s.normals).all()
    np.testing.assert_allclose(np.linalg.norm(s.normals, axis=-1), 1.0, atol=1e-5)
    assert (s.normals[..., 2] >= 0).all()
    again = ps.make_surface(name, size=size)
    assert np.array_equal(s.height, again.height) and np.array_equal(s.normals, again.normals)


@pytest.mark.parametrize("name", ["semisphere", "spheres", "sombrero1", "sombrero2", "sombrero3"])
def test_analytic_normals_agree_with_height_gradient(name):
    s = ps.make_surface(name, size=256)
    numeric = normals_from_height(s.height.astype(np.float64))
    # compare on the interior, away from silhouettes where the slope is discontinuous
    ok = cv2.erode(s.object_mask.astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    steep = cv2.dilate((s.zenith >= 60).astype(np.uint8), np.ones((7, 7), np.uint8)).astype(bool)
    ok &= ~steep
    cosang = np.clip((numeric[ok] * s.normals[ok]).sum(-1), -1, 1)
    assert np.degrees(np.arccos(cosang)).mean() < 0.5


def test_sombrero_zeniths_follow_the_peaks():
    z = [ps.make_surface(f"sombrero{i}", size=512).zenith.max() for i in (1, 2, 3)]
    assert abs(z[1] - 66.0) < 0.5
    assert z[0] < z[1] < z[2]
    assert SOMBRERO_LAMBDA > 0
    assert np.array_equal(ps.make_surface("sombrero", size=64).height,
                          ps.make_surface("sombrero2", size=64).height)


def test_semisphere_is_a_hemisphere():
    size = 128
    s = ps.make_surface("semisphere", size=size)
    x, y = np.broadcast_arrays(*pixel_grid((size, size)))
    r2 = x ** 2 + y ** 2
    R = 0.45 * size
    inside = s.object_mask & (r2 < (0.95 * R) ** 2)
    np.testing.assert_allclose(s.height[inside], np.sqrt(R ** 2 - r2[inside]), rtol=1e-4, atol=1e-3)
    # the ground plane is part of the object (flat, height 0, normal +z); the disc-only
    # scene has the same arrays with the disc as object mask
    assert s.object_mask.all()
    out = r2 > (1.05 * R) ** 2
    assert (s.height[out] == 0).all() and (s.normals[out] == (0, 0, 1)).all()
    d = ps.make_surface("semisphere_disc", size=size)
    assert d.name == "semisphere_disc"
    np.testing.assert_array_equal(d.object_mask, r2 < R ** 2)
    np.testing.assert_array_equal(d.height, s.height)
    np.testing.assert_array_equal(d.normals, s.normals)
    assert ps.make_surface("semisphere", size=size, plane=False).object_mask.sum() == d.object_mask.sum()


def test_semisphere_plane_receives_cast_shadows_that_count():
    # at 60 deg the hemisphere shades the plane around it: those observations are on
    # the object (they count in NE); on the disc-only scene they are not
    s = ps.make_surface("semisphere", size=96)
    d = ps.make_surface("semisphere_disc", size=96)
    sc = ps.render(s, ps.layout("60x4"))
    on_plane = sc.cast_shadow & ~d.object_mask[None]
    assert on_plane.any(axis=0).mean() > 0.02
    assert not (ps.render(d, ps.layout("60x4")).cast_shadow & ~d.object_mask[None]).any()


@pytest.mark.parametrize("name", ["mozart", "penny", "spheres"])
def test_bust_coin_and_spheres_have_steep_sides_that_cast_shadows(name):
    s = ps.make_surface(name, size=128)
    assert (s.zenith[s.object_mask] > 60).any()
    shadow = ps.shadow_map(s.height, ps.layout("60x4"), object_mask=s.object_mask)
    assert shadow.any(axis=0).mean() > 0.005


def test_surface_from_height_plane_and_paraboloid():
    H, W = 40, 50
    x, y = np.broadcast_arrays(*pixel_grid((H, W)))
    plane = 0.5 * x - 0.25 * y
    s = ps.surface_from_height(plane)
    want = np.array([-0.5, 0.25, 1.0]) / np.linalg.norm([-0.5, 0.25, 1.0])
    np.testing.assert_allclose(s.normals.reshape(-1, 3), np.broadcast_to(want, (H * W, 3)), atol=1e-5)
    para = 10 - 0.01 * (x ** 2 + y ** 2)
    sp = ps.surface_from_height(para, name="bowl")
    n = sp.normals[H // 2 - 5, W // 2 + 7]  # x = 7.5, y = 5.5 (grid is centred between pixels)
    xx, yy = x[H // 2 - 5, W // 2 + 7], y[H // 2 - 5, W // 2 + 7]
    g = np.array([0.02 * xx, 0.02 * yy, 1.0])
    np.testing.assert_allclose(n, g / np.linalg.norm(g), atol=1e-4)
    assert sp.name == "bowl"


def test_surface_from_file_npy_and_png(tmp_path):
    h = ps.make_surface("semisphere", size=64).height
    np.save(tmp_path / "h.npy", h)
    s = ps.surface_from_file(tmp_path / "h.npy")
    np.testing.assert_allclose(s.height, h, atol=1e-6)
    png = (h / h.max() * 65535).round().astype(np.uint16)
    cv2.imwrite(str(tmp_path / "h.png"), png)
    sp = ps.surface_from_file(tmp_path / "h.png", scale=float(h.max()))
    np.testing.assert_allclose(sp.height, h, atol=float(h.max()) / 65535 + 1e-4)
    assert sp.name == "h"


@pytest.mark.parametrize("call, words", [
    (lambda: ps.make_surface("teapot"), "valid choices"),
    (lambda: ps.make_surface("semisphere", size=4), "size"),
    (lambda: ps.surface_from_height(np.full((8, 8), np.nan)), "NaN"),
    (lambda: ps.surface_from_height(np.zeros(8)), "shape"),
    (lambda: ps.surface_from_height(np.zeros((8, 8)), object_mask=np.ones((4, 4), bool)),
     "object_mask"),
    (lambda: ps.surface_from_file("heights.txt"), ".npy, .png or .x3p"),
    (lambda: ps.surface_from_file("missing.npy"), "does not exist"),
])
def test_bad_input_gives_clear_errors(call, words):
    with pytest.raises(ps.PsbenchError) as err:
        call()
    assert words in str(err.value)


def test_preview_command_writes_pngs(tmp_path):
    from psbench.surfaces import main

    main(["--out", str(tmp_path), "--size", "32", "--names", "semisphere", "penny"])
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["penny.png", "semisphere.png"]
    assert cv2.imread(str(tmp_path / "penny.png")) is not None


@pytest.mark.parametrize("name", ["mozart", "penny", "spheres"])
def test_background_plane_is_at_height_zero(name):
    s = ps.make_surface(name, size=96)
    assert s.object_mask[0, 0] and abs(float(s.height[0, 0])) < 1e-4
    assert np.allclose(s.normals[0, 0], (0, 0, 1))


def test_preview_command_keeps_existing_pngs_unless_overwrite(tmp_path, capsys):
    from psbench.surfaces._preview import main

    png = tmp_path / "spheres.png"
    png.write_bytes(b"committed")
    assert main(["--out", str(tmp_path), "--size", "32", "--names", "spheres"]) == 0
    assert png.read_bytes() == b"committed" and "--overwrite" in capsys.readouterr().out
    assert main(["--out", str(tmp_path), "--size", "32", "--names", "spheres",
                 "--overwrite"]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG"
