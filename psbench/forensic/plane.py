"""Sample-plane correction (thesis Section 1.4).

"Since the relative positioning of the sample with respect to the camera determines the
amount of highlights and shadows on the images, a priori adjustment of orientation has a
potential to improve 3D generation performance." A case head is a plane with a few
marks; held slightly tilted, its face moves towards one ring's mirror directions and its
firing-pin walls shadow differently.

- :func:`estimate_plane` estimates the sample's mean plane from the normals of a first
  least-squares pass (robust mean of the normals near the dominant orientation) and
  reports its tilt and azimuth.
- :func:`tilt_surface` / :func:`rotate_surface` rotate a surface rigidly about the image
  centre (the simulated rig's pitch/yaw stage); :func:`reorient` undoes an estimated
  plane with it, i.e. the re-capture with the corrected orientation, and
  :func:`level_sample` repeats estimate-and-turn until the sample is level.
- :func:`level` is the computational correction: it fits the mean plane of reconstructed
  heights (least squares with outlier trimming) and subtracts it.

Angles are in degrees. The tilt is the angle between the plane normal and the view
axis +z; the azimuth is the direction of the normal's horizontal part, counter-clockwise
from +x (the plane rises towards azimuth + 180°).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from .._shared.checks import PsbenchError, as_mask
from ..surfaces import Surface

__all__ = ["Plane", "estimate_plane", "level", "tilt_surface", "rotate_surface", "reorient",
           "level_sample", "rotation"]


@dataclass(frozen=True)
class Plane:
    """A sample plane.

    Attributes
    ----------
    normal : (3,) float64
        Unit normal (z > 0).
    tilt : float
        Degrees between ``normal`` and +z.
    azimuth : float
        Degrees, direction of the normal's horizontal part, counter-clockwise from +x, in
        [0, 360).
    pixels : int
        Pixels the estimate used.
    """

    normal: np.ndarray
    tilt: float
    azimuth: float
    pixels: int = 0

    @classmethod
    def from_normal(cls, n, pixels=0):
        n = np.asarray(n, np.float64)
        n = n / np.linalg.norm(n)
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, float(n[2])))))
        az = math.degrees(math.atan2(n[1], n[0])) % 360.0 if tilt > 0 else 0.0
        return cls(n, tilt, az, int(pixels))

    @classmethod
    def from_angles(cls, tilt, azimuth=0.0):
        t, a = math.radians(float(tilt)), math.radians(float(azimuth))
        return cls.from_normal([math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), math.cos(t)])


def _angle(value, name, lo=-90.0, hi=90.0):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be a number of degrees, got {value!r}") from None
    if not math.isfinite(v) or not lo <= v <= hi:
        raise PsbenchError(f"{name} must be in [{lo:g}, {hi:g}] degrees, got {value!r}")
    return v


def estimate_plane(normals, object_mask=None, *, max_angle=10.0, rounds=4):
    """Mean plane of a mostly flat sample from its (least-squares) normals.

    Starts from the component-wise median normal, then ``rounds`` times averages the
    unit normals within ``max_angle`` of the current estimate. Walls, bevels, letters
    and the firing-pin crater fall outside that cone; shallow marks average out.

    Parameters
    ----------
    normals : (H, W, 3) array_like
        E.g. ``ps.solve(...).normals``.
    object_mask : (H, W) bool, optional
        Pixels of the sample (default all).
    max_angle : float, default 10
        Degrees; the cone of normals that count as the face.
    rounds : int, default 4

    Returns
    -------
    Plane
    """
    n = np.asarray(normals, np.float32)
    if n.ndim != 3 or n.shape[2] != 3:
        raise PsbenchError(f"normals must have shape (H, W, 3), got {n.shape}")
    m = as_mask(object_mask, n.shape[:2], "object_mask")
    max_angle = _angle(max_angle, "max_angle", 0.1, 90.0)
    v = n[m]
    v = v[np.isfinite(v).all(axis=1)]
    if len(v) < 3:
        raise PsbenchError("object_mask selects fewer than 3 pixels with finite normals")
    v = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
    est = np.median(v, axis=0).astype(np.float64)
    cos_lim = math.cos(math.radians(max_angle))
    used = len(v)
    for _ in range(int(rounds)):
        est /= np.linalg.norm(est)
        near = v @ est.astype(np.float32) >= cos_lim
        used = int(near.sum())
        if used < 3:
            break
        est = v[near].mean(axis=0, dtype=np.float64)
    return Plane.from_normal(est, used)


def level(height, object_mask=None, *, pixel_size=1.0, trim=3.0, rounds=3):
    """Computational plane correction: fit the mean plane of heights and subtract it.

    Least squares ``z = a x + b y + c`` over ``object_mask``, refitted ``rounds`` times
    without the pixels whose residual exceeds ``trim`` robust standard deviations (1.4826
    MAD) -- the firing-pin crater, letters and the bevel.

    Parameters
    ----------
    height : (H, W) array_like
        Heights (pixel units, or µm with ``pixel_size`` in µm).
    object_mask : (H, W) bool, optional
    pixel_size : float, default 1
        Lateral size of a pixel in the heights' unit.
    trim : float, default 3
    rounds : int, default 3

    Returns
    -------
    levelled : (H, W) float32
        ``height`` minus the plane, 0 outside ``object_mask``.
    plane : Plane
        The fitted plane (tilt and azimuth of its normal).
    """
    z = np.asarray(height, np.float64)
    if z.ndim != 2:
        raise PsbenchError(f"height must have shape (H, W), got {z.shape}")
    m = as_mask(object_mask, z.shape, "object_mask") & np.isfinite(z)
    if m.sum() < 3:
        raise PsbenchError("object_mask selects fewer than 3 finite heights")
    ps = float(pixel_size)
    if not math.isfinite(ps) or ps <= 0:
        raise PsbenchError(f"pixel_size must be a finite number > 0, got {pixel_size!r}")
    H, W = z.shape
    x = (np.arange(W) - (W - 1) / 2.0) * ps
    y = ((H - 1) / 2.0 - np.arange(H)) * ps
    rr, cc = np.nonzero(m)
    X, Y, Z = x[cc], y[rr], z[rr, cc]
    keep = np.ones(len(Z), bool)
    coef = np.zeros(3)
    for _ in range(int(rounds) + 1):
        A = np.column_stack([X[keep], Y[keep], np.ones(int(keep.sum()))])
        coef = np.linalg.lstsq(A, Z[keep], rcond=None)[0]
        res = Z - (coef[0] * X + coef[1] * Y + coef[2])
        mad = 1.4826 * np.median(np.abs(res[keep] - np.median(res[keep])))
        if mad <= 0:
            break
        keep = np.abs(res - np.median(res[keep])) <= trim * mad
    plane = Plane.from_normal([-coef[0], -coef[1], 1.0], int(keep.sum()))
    out = np.zeros((H, W), np.float32)
    out[m] = (Z - (coef[0] * X + coef[1] * Y + coef[2])).astype(np.float32)
    return out, plane


def rotation(tilt, azimuth=0.0):
    """(3, 3) rotation taking +z to the normal of ``Plane.from_angles(tilt, azimuth)``."""
    t, a = math.radians(tilt), math.radians(azimuth)
    k = np.array([-math.sin(a), math.cos(a), 0.0])          # axis z x d
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(t) * K + (1 - math.cos(t)) * (K @ K)


def tilt_surface(surface, tilt, azimuth=0.0, *, iterations=4):
    """Tilt a surface rigidly by ``tilt`` degrees towards ``azimuth`` (the rig's stage).

    :func:`rotate_surface` with :func:`rotation` ``(tilt, azimuth)``: +z goes to the
    direction (tilt, azimuth), so a level sample gets that plane normal.

    Parameters
    ----------
    surface : Surface or Cartridge
    tilt : float
        Degrees in [-45, 45].
    azimuth : float, default 0
        Degrees.
    iterations : int, default 4

    Returns
    -------
    Surface or Cartridge
    """
    tilt = _angle(tilt, "tilt", -45.0, 45.0)
    azimuth = _angle(azimuth, "azimuth", -360.0, 720.0)
    return rotate_surface(surface, rotation(tilt, azimuth), iterations=iterations)


def rotate_surface(surface, R, *, iterations=4):
    """Rotate a height-field surface rigidly by the (3, 3) rotation ``R``.

    The rotation is about the image centre at height 0 (pixel units). The new height
    field is resampled on the same pixel grid by fixed-point inversion of the lateral
    displacement (bicubic heights, so fine marks survive); masks and regions follow
    with nearest-neighbour sampling, albedo bicubic; normals are recomputed by central
    differences. Where the rotation would fold the field (walls steeper than
    90° - tilt) the visible sheet is not resolved exactly.

    Returns
    -------
    Surface or Cartridge
        Same type; a Cartridge's ``pose`` records the ``tilt`` and ``tilt_azimuth`` of
        its face normal after the rotation.
    """
    R = np.asarray(R, np.float64)
    if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-6):
        raise PsbenchError(f"R must be a (3, 3) rotation matrix, got shape {R.shape}")
    h = np.asarray(surface.height, np.float32)
    H, W = h.shape
    Rf = R.astype(np.float32)
    xs = np.arange(W, dtype=np.float32) - np.float32((W - 1) / 2)
    ys = np.float32((H - 1) / 2) - np.arange(H, dtype=np.float32)
    X, Y = np.broadcast_to(xs[None, :], (H, W)), np.broadcast_to(ys[:, None], (H, W))
    x, y = X.copy(), Y.copy()
    for _ in range(int(iterations)):     # find the source point that lands on each pixel
        z = _sample(h, x, y, W, H, cv2.INTER_LINEAR)
        xp = Rf[0, 0] * x + Rf[0, 1] * y + Rf[0, 2] * z
        yp = Rf[1, 0] * x + Rf[1, 1] * y + Rf[1, 2] * z
        x += X - xp
        y += Y - yp
    z = _sample(h, x, y, W, H, cv2.INTER_CUBIC)
    new_h = Rf[2, 0] * x + Rf[2, 1] * y + Rf[2, 2] * z
    object_mask = _sample(np.asarray(surface.object_mask, np.uint8), x, y, W, H,
                          cv2.INTER_NEAREST) > 0
    d_row, d_col = np.gradient(new_h)
    inv = 1.0 / np.sqrt(1.0 + d_col * d_col + d_row * d_row)
    normals = np.stack([-d_col * inv, d_row * inv, inv], axis=-1).astype(np.float32)
    normals[~object_mask] = (0.0, 0.0, 1.0)
    if not hasattr(surface, "regions"):
        return Surface(name=f"{surface.name}(rotated)", height=new_h, object_mask=object_mask,
                       normals=normals)
    regions = {k: _sample(v.astype(np.uint8), x, y, W, H, cv2.INTER_NEAREST) > 0
               for k, v in surface.regions.items()}
    regions["case"] = object_mask
    albedo = _sample(np.asarray(surface.albedo, np.float32), x, y, W, H, cv2.INTER_CUBIC)
    pose = dict(surface.pose)
    prev = Plane.from_angles(pose.get("tilt", 0.0), pose.get("tilt_azimuth", 0.0)).normal
    now = Plane.from_normal(R @ prev)
    pose["tilt"], pose["tilt_azimuth"] = now.tilt, now.azimuth
    return replace(surface, height=new_h, object_mask=object_mask, normals=normals,
                   regions=regions, albedo=albedo, pose=pose)


def reorient(surface, plane):
    """Re-capture orientation: rotate ``surface`` so that ``plane`` (an estimate of its
    mean plane, e.g. from :func:`estimate_plane`) faces the camera."""
    return tilt_surface(surface, -plane.tilt, plane.azimuth)


def level_sample(surface, estimate, *, tol=0.05, max_rounds=5):
    """Closed-loop orientation correction on the (simulated) rig.

    Each round captures the sample in its current orientation, estimates its plane with
    ``estimate(surface) -> Plane`` (e.g. acquire, a first least-squares or Th pass,
    :func:`estimate_plane`), and turns the stage to undo it; it stops when the estimated
    tilt is below ``tol`` degrees. The stage's rotations are composed and applied to
    ``surface`` in one resampling per capture. A biased estimator (highlights pull
    least-squares normals towards the lights, exaggerating a tilt by a factor g)
    still converges when 0 < g < 2, because a level sample is estimated level.

    Parameters
    ----------
    surface : Surface or Cartridge
        The sample as mounted (tilted).
    estimate : callable
        ``estimate(surface) -> Plane``.
    tol : float, default 0.05
    max_rounds : int, default 5
        Captures at most (the last one is the level sample).

    Returns
    -------
    levelled : Surface or Cartridge
        The sample after the last stage move.
    mounted : Plane
        The mount's tilt as recovered by the loop: the plane normal the composed stage
        rotation took to +z.
    history : list of Plane
        The estimate of every capture.
    """
    tol = _angle(tol, "tol", 0.0, 45.0)
    if isinstance(max_rounds, bool) or not isinstance(max_rounds, (int, np.integer)) \
            or max_rounds < 1:
        raise PsbenchError(f"max_rounds must be an integer >= 1, got {max_rounds!r}")
    Rc = np.eye(3)
    current, history = surface, []
    for _ in range(int(max_rounds)):
        plane = estimate(current)
        history.append(plane)
        if plane.tilt <= tol:
            break
        Rc = rotation(-plane.tilt, plane.azimuth) @ Rc
        current = rotate_surface(surface, Rc)
    return current, Plane.from_normal(Rc.T @ np.array([0.0, 0.0, 1.0])), history


def _sample(img, x, y, W, H, interp):
    """Sample ``img`` at psbench-frame coordinates (x right, y up, centred)."""
    mx = (x + np.float32((W - 1) / 2)).astype(np.float32)
    my = (np.float32((H - 1) / 2) - y).astype(np.float32)
    border = float(img.min()) if img.dtype != np.uint8 else 0
    return cv2.remap(img, mx, my, interp, borderMode=cv2.BORDER_CONSTANT, borderValue=border)
