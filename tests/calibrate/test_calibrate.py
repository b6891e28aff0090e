"""Calibration steps: each one alone removes the imperfection it targets (measured on the
simulated rig with only that imperfection switched on), plus file/CLI behaviour."""
from __future__ import annotations

import json

import numpy as np
import pytest

from psbench import PsbenchError
from psbench import calibrate as cal
from psbench.calibrate._fit import _norm_coords
from psbench.capture.sim import RigConfig, SimRig
from psbench.solve.kernel import ls, split

SIZE = 96


def frames(rig, target, *, leds=None):
    """Frames of ``target`` with each LED in turn (or one frame with no LED), in [0, 1]."""
    mA = rig.config.current_mA
    if leds is None:
        cur = [np.eye(rig.k)[i] * mA for i in range(rig.k)]
    else:
        cur = leds
    top = 2 ** rig.config.bits - 1
    return np.stack([rig.expose(rig.radiance(target, c)) for c in cur]).astype(np.float32) / top


def _ne(n, truth, mask):
    return float(np.degrees(np.arccos(np.clip((n * truth).sum(-1), -1, 1)))[mask].mean())


def _ang(a, b):
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))


# --------------------------------------------------------------------------- response
def test_response_linearises():
    rig = SimRig(RigConfig.ideal(size=SIZE, gamma=2.2, bits=16))
    chart = frames(rig, "chart", leds=[np.zeros(rig.k)])[0]
    m = cal.chart_means(chart, rig.chart_boxes)
    c = cal.fit_response(m, rig.chart_radiance, degree=6)
    # held-out ramp of exposures through the camera model
    e = np.linspace(0.03, 0.95, 60)
    out = rig.response(e)

    def lin_err(v):  # max deviation from the best line through the origin, % of range
        k = (v @ e) / (e @ e)
        return 100 * np.abs(v - k * e).max() / (k * e.max())

    before, after = lin_err(out), lin_err(cal.apply_response(out, c).astype(float))
    print(f"response linearity error: {before:.2f}% -> {after:.3f}%")
    assert before > 15 and after < 0.2
    assert c.size == 7  # the thesis's 6th order is kept
    assert np.all(np.diff(cal.apply_response(np.linspace(0, 1, 500), c)) >= 0)


def test_response_degree_lowered_when_not_monotone():
    m = np.array([0.1, 0.2, 0.3, 0.4, 0.42, 0.6])
    r = np.array([0.1, 0.2, 0.3, 0.4, 0.5, 0.6])
    with pytest.warns(UserWarning, match="not monotone"):
        c = cal.fit_response(m, r, degree=6)
    assert c.size < 7
    with pytest.raises(PsbenchError, match="order"):
        cal.fit_response([0.5, 0.4, 0.3], [0.1, 0.2, 0.3])


# --------------------------------------------------------------------------- flat field
def test_flat_field_removes_vignette():
    rig = SimRig(RigConfig.ideal(size=SIZE, vignette=0.3, bits=16))
    white = frames(rig, "white")
    flat = cal.flat_field(white, degree=4)
    held_out = frames(SimRig(RigConfig.ideal(size=SIZE, vignette=0.3, bits=16, seed=3)), "white")

    def nonuni(img):
        return 100 * img.std() / img.mean()

    before = np.mean([nonuni(w) for w in held_out])
    after = np.mean([nonuni(w / flat) for w in held_out])
    print(f"flat-field non-uniformity: {before:.2f}% -> {after:.3f}%")
    assert before > 5 and after < 0.2
    assert flat[SIZE // 2, SIZE // 2] == pytest.approx(1.0, abs=0.01)


def test_polyfit2d_recovers_polynomial():
    H, W = 40, 50
    u, v = _norm_coords((H, W))
    img = 1 + 0.3 * u[None, :] - 0.2 * v[:, None] ** 2 + 0.1 * u[None, :] * v[:, None]
    c = cal.polyfit2d(img, degree=2)
    assert np.allclose(cal.polyval2d(c, (H, W), 2), img, atol=1e-10)


# --------------------------------------------------------------------------- dark / hot pixels
def test_hot_pixels_removed():
    rig = SimRig(RigConfig.ideal(size=SIZE, hot_pixels=30, read_noise=0.002))
    clean = SimRig(RigConfig.ideal(size=SIZE, hot_pixels=0, read_noise=0.002))
    dark = frames(rig, "dark", leds=[np.zeros(rig.k)])[0]
    hot, thr = cal.hot_pixels(dark)
    assert np.array_equal(hot, rig.hot_mask)
    imgs = frames(rig, "white")
    ref = frames(clean, "white")

    def count(x):
        return int((np.abs(x - ref) > 0.05).sum())

    fixed = cal.remove_hot_pixels(imgs, hot)
    print(f"hot pixels: {count(imgs)} -> {count(fixed)} (threshold {thr:.3f})")
    assert count(imgs) == 30 * rig.k and count(fixed) == 0
    with pytest.raises(PsbenchError, match="hot must have shape"):
        cal.remove_hot_pixels(imgs, hot[:5])


# --------------------------------------------------------------------------- light directions
def test_sphere_light_directions():
    rig = SimRig(RigConfig.ideal(size=128, misplace_deg=3.0, sphere_m=400.0))
    from psbench.surfaces import make_surface
    mask = make_surface("semisphere_disc", size=128).object_mask
    sph = frames(rig, "sphere")
    d, n, pts = cal.light_directions_from_sphere(sph, object_mask=mask)
    err = _ang(d, rig.directions)
    nominal = _ang(rig.nominal.directions, rig.directions)
    print(f"light direction error: nominal {nominal.mean():.2f} deg -> sphere {err.mean():.3f} deg "
          f"(max {err.max():.3f})")
    assert err.max() < 0.5 and nominal.mean() > 1.5


def test_sphere_light_positions_near():
    rig = SimRig(RigConfig.ideal(size=128, distance=5 * 128, misplace_deg=2.0))
    from psbench.surfaces import make_surface
    mask = make_surface("semisphere_disc", size=128).object_mask
    d, n, _ = cal.light_directions_from_sphere(frames(rig, "sphere"), object_mask=mask)
    cx, cy, R = cal.sphere_geometry(mask)
    P = cal.light_positions(d, n, rig.distance, center=(cx, cy), radius=R)
    err = np.linalg.norm(P - rig.positions, axis=1) / rig.distance
    dir_err = _ang(P / np.linalg.norm(P, axis=1)[:, None], rig.directions)
    naive = _ang(d, rig.directions)  # reflection vector alone, ignoring the near field
    print(f"near lights: direction error {naive.mean():.2f} deg (reflection only) -> "
          f"{dir_err.mean():.3f} deg (positions); position error {100 * err.max():.2f}% of distance")
    assert dir_err.max() < 0.6 and err.max() < 0.01
    with pytest.raises(PsbenchError, match="exceed the sphere radius"):
        cal.light_positions(d, n, 1.0, center=(cx, cy), radius=R)


# --------------------------------------------------------------------------- powers
def test_light_powers():
    rig = SimRig(RigConfig.ideal(size=SIZE, power_spread=0.2, bits=16))
    white = frames(rig, "white")
    p = cal.light_powers(white, rig.directions)
    truth = rig.powers / rig.powers.mean()
    naive = white.mean(axis=(1, 2)) / white.mean()  # mean intensity without the cos factor
    e_naive = 100 * np.abs(naive / truth - 1).max()
    e = 100 * np.abs(p / truth - 1).max()
    print(f"power ratio error: {e_naive:.2f}% (mean only) -> {e:.3f}% (mean / cos zenith)")
    assert e < 0.3 and e_naive > 10


# --------------------------------------------------------------------------- near light
def test_near_light_correction_improves_ne():
    rig = SimRig(RigConfig.ideal(size=SIZE, distance=3 * SIZE, model="lambert", bits=16))
    imgs = frames(rig, "object").astype(np.float32) / rig.config.exposure
    from psbench.lights import layout
    lay = layout(rig.directions)
    m = rig.surface.object_mask
    ne_raw = _ne(split(ls(imgs, lay.S))[0], rig.surface.normals, m)
    near = cal.near_light_fields(imgs.shape[1:], rig.positions)
    ne_cor = _ne(split(ls(imgs / near, lay.S))[0], rig.surface.normals, m)
    ideal = rig.ideal()
    ne_ideal = _ne(split(ls(ideal.images, lay.S))[0], rig.surface.normals, m)
    print(f"near-light NE: {ne_raw:.2f} -> {ne_cor:.2f} deg (distant ideal {ne_ideal:.2f})")
    assert ne_cor < ne_raw - 0.5
    # what remains is mostly the geometry of point-light cast shadows (a different scene
    # from distant lights); without cast shadows the corrected NE is at the distant ideal
    from psbench.render import render
    s = rig.surface
    kw = dict(model="lambert", rho_d=0.8, shadows=False)
    near_ns = render(s, lay, light_positions=rig.positions, falloff=True, **kw).images
    far_ns = render(s, lay, **kw).images
    ne_ns_raw = _ne(split(ls(near_ns, lay.S))[0], s.normals, m)
    ne_ns = _ne(split(ls(near_ns / near, lay.S))[0], s.normals, m)
    ne_ns_far = _ne(split(ls(far_ns, lay.S))[0], s.normals, m)
    print(f"near-light NE without cast shadows: {ne_ns_raw:.2f} -> {ne_ns:.2f} deg "
          f"(distant {ne_ns_far:.2f})")
    assert ne_ns < ne_ns_far + 0.2 < ne_ns_raw
    # the rendered plane is exactly the white target's shape
    white = frames(rig, "white").astype(np.float64)
    ratio = white / near
    assert (ratio.std(axis=(1, 2)) / ratio.mean(axis=(1, 2))).max() < 2e-3


# --------------------------------------------------------------------------- pixel size
@pytest.mark.parametrize("pixel_mm", [0.0732, 0.0932, 0.15])
def test_pixel_size(pixel_mm):
    rig = SimRig(RigConfig.ideal(size=128, pixel_mm=pixel_mm))
    grid = frames(rig, "grid", leds=[np.zeros(rig.k)])[0]
    got = cal.pixel_size(grid, 1.0)
    print(f"pixel size {pixel_mm} mm -> {got:.5f} mm ({100 * (got / pixel_mm - 1):+.3f}%)")
    assert got == pytest.approx(pixel_mm, rel=0.005)


# --------------------------------------------------------------------------- file + apply + CLI
def test_save_load_apply_order(tmp_path):
    rng = np.random.default_rng(0)
    c = cal.Calibration(directions=np.tile([0, 0, 1.0], (3, 1)), powers=np.array([1, 2, 4.0]),
                        flat=np.full((5, 6), 0.5, np.float32),
                        response=np.array([1.0, 0.0, 0.0]),  # g(m) = m^2
                        hot=np.zeros((5, 6), bool), hot_threshold=0.5, pixel_size=0.01)
    c.hot[2, 3] = True
    cal.save_calibration(c, tmp_path / "cal")
    d = cal.load_calibration(tmp_path / "cal")
    assert d.steps() == ["dark", "response", "directions", "flat", "powers", "pixelsize"]
    assert np.array_equal(d.hot, c.hot) and d.pixel_size == 0.01
    imgs = rng.uniform(0.2, 0.4, (3, 5, 6)).astype(np.float32)
    imgs[:, 2, 3] = 1.0
    out = cal.apply_calibration(imgs, d)
    # order: hot pixel replaced BEFORE the response (median of neighbours, then squared)
    import cv2
    med = cv2.medianBlur(imgs[0], 3)[2, 3]
    assert out[0, 2, 3] == pytest.approx(med ** 2 / 0.5 / 1.0, rel=1e-5)
    assert np.allclose(out[2, 0, 0], imgs[2, 0, 0] ** 2 / 0.5 / 4.0, rtol=1e-5)
    with pytest.raises(PsbenchError, match="light powers for 2 images"):
        cal.apply_calibration(imgs[:2], d)
    with pytest.raises(PsbenchError, match="no calibration.json"):
        cal.load_calibration(tmp_path)


@pytest.mark.filterwarnings("ignore:response fit")
def test_cli_steps_incremental(tmp_path, capsys):
    from psbench.capture import LedController, capture_all
    from psbench.capture.sim import SimController
    rig = SimRig(RigConfig(size=64, lights="30x4+60x4", surface="semisphere"))
    out = tmp_path / "cap"
    with SimController(rig.k) as dev, LedController(dev.port, timeout=0.5) as ctl:
        capture_all(rig, ctl, out, device=dev, progress=False)
    raw, cdir = out / "calibration_raw", tmp_path / "cal"
    assert cal.main(["dark", str(out), "--out", str(cdir)]) == 0
    assert cal.main(["response", str(raw / "chart"), "--out", str(cdir)]) == 0
    assert cal.main(["directions", str(raw / "sphere"), "--out", str(cdir)]) == 0
    assert cal.main(["flat", str(raw / "white"), "--out", str(cdir)]) == 0
    assert cal.main(["powers", str(raw / "white"), "--out", str(cdir)]) == 0
    assert cal.main(["pixelsize", str(raw / "grid"), "--out", str(cdir)]) == 0
    c = cal.load_calibration(cdir)
    assert c.steps() == ["dark", "response", "directions", "nearlight", "flat", "powers", "pixelsize"]
    assert cal.main(["show", str(cdir)]) == 0
    assert json.loads(capsys.readouterr().out.split("\n", 6)[-1] or "{}") is not None
    # an explicit calibration path given to read_dataset
    from psbench.io import read_dataset
    ds = read_dataset(out, calibration=cdir)
    assert ds.meta["calibrated"] and ds.lights.positions is not None
    assert cal.main(["response", str(tmp_path / "missing"), "--out", str(cdir)]) == 2
    # sphere without a mask: centre and radius given on the command line
    import shutil
    sph = tmp_path / "sphere"
    shutil.copytree(raw / "sphere", sph)
    (sph / "mask.png").unlink()
    c2 = tmp_path / "cal2"
    assert cal.main(["directions", str(sph), "--out", str(c2)]) == 2
    R = float(np.sqrt(cal.load_calibration(cdir).meta["sphere"]["radius"] ** 2))
    assert cal.main(["directions", str(sph), "--out", str(c2), "--center", "0", "0",
                     "--radius", str(R)]) == 0
    d1, d2 = cal.load_calibration(cdir).directions, cal.load_calibration(c2).directions
    assert _ang(d1, d2).max() < 1.0  # 64 px sphere: the mask edge vs the exact circle
