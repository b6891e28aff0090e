"""Sample-plane correction: estimate, tilt, level, closed-loop re-capture."""
import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError
from psbench.forensic import (Plane, acquire, estimate_plane, level, level_sample,
                              make_cartridge, reorient, rotate_surface, tilt_surface)
from psbench.forensic.plane import rotation


@pytest.fixture(scope="module")
def case():
    return make_cartridge(300, gun=2, case=7)


def _angle(a, b):
    return float(np.degrees(np.arccos(np.clip(a.normal @ b.normal, -1, 1))))


@pytest.mark.parametrize("tilt, az", [(3.0, 30.0), (-2.0, 200.0), (10.0, 300.0)])
def test_rotation_takes_z_to_the_plane_normal(tilt, az):
    R = rotation(tilt, az)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(R @ [0, 0, 1], Plane.from_angles(tilt, az).normal, atol=1e-12)


def test_tilt_surface_and_ground_truth_estimate(case):
    t = tilt_surface(case, 3.0, 30.0)
    assert t.pose["tilt"] == pytest.approx(3.0) and t.pose["tilt_azimuth"] == pytest.approx(30.0)
    est = estimate_plane(t.normals, t.object_mask)
    assert _angle(est, Plane.from_angles(3.0, 30.0)) < 0.05
    # heights: a plane of slope tan(3 deg) in the 30-degree direction was added
    _, fitted = level(t.height, t.object_mask)
    assert _angle(fitted, Plane.from_angles(3.0, 30.0)) < 0.05
    back = reorient(t, est)
    m = back.object_mask & case.object_mask & ~case.regions["firing_pin"]
    assert np.median(np.abs(back.height - case.height)[m]) * case.pixel_size < 1.0   # µm
    assert back.pose["tilt"] < 0.05


def test_level_recovers_a_known_plane():
    H, W = 64, 80
    x = np.arange(W) - (W - 1) / 2
    y = (H - 1) / 2 - np.arange(H)[:, None]
    z = 0.05 * x - 0.02 * y + 3.0 + 0 * y
    z[20:30, 20:30] -= 40.0            # a crater the trimming must ignore
    out, plane = level(z)
    expected = Plane.from_normal([-0.05, 0.02, 1.0])
    assert _angle(plane, expected) < 1e-6
    assert np.abs(out[40:, 40:]).max() < 1e-9


def test_closed_loop_recovers_a_known_tilt(case):
    """Acceptance: plane correction recovers a known tilt to < 0.1 degrees (from PS
    normals, not from the ground truth)."""
    mounted = tilt_surface(case, 3.0, 30.0)

    def first_pass(s):
        a = acquire(s)
        return estimate_plane(ps.solve(a.images, a.lights, mask="Th", object_mask=s.object_mask).normals,
                              s.object_mask)

    levelled, recovered, history = level_sample(mounted, first_pass, tol=0.05, max_rounds=6)
    assert _angle(recovered, Plane.from_angles(3.0, 30.0)) < 0.1
    assert levelled.pose["tilt"] < 0.1
    assert history[-1].tilt <= 0.05 and len(history) >= 2


def test_rotate_plain_surface():
    s = ps.make_surface("sombrero", size=64)
    r = rotate_surface(s, rotation(2.0, 90.0))
    assert isinstance(r, ps.Surface) and r.height.shape == (64, 64)


@pytest.mark.parametrize("call, word", [
    (lambda c: tilt_surface(c, 60.0), "tilt"),
    (lambda c: tilt_surface(c, "x"), "tilt"),
    (lambda c: rotate_surface(c, np.eye(2)), "R"),
    (lambda c: estimate_plane(c.normals[..., :2]), "normals"),
    (lambda c: estimate_plane(c.normals, max_angle=0), "max_angle"),
    (lambda c: level(c.height, pixel_size=0), "pixel_size"),
    (lambda c: level_sample(c, lambda s: Plane.from_angles(0), max_rounds=0), "max_rounds"),
])
def test_bad_input(case, call, word):
    with pytest.raises(PsbenchError, match=word):
        call(case)
