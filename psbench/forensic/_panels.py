"""Illustrations of the Chapter 7 study (Figs. 7.3-7.9 analogues) as small encoded images.

The study's ``panels`` run (:func:`psbench.forensic.study.run`) computes these from one
sister pair and stores them, base64-encoded PNG or JPEG, in its json payload, so the
report draws them from the store without solving anything. Helpers:

- :func:`encode` / :func:`decode`: uint8 (H, W) or (H, W, 3) RGB <-> base64 text;
- :func:`montage`: the 16 images of a stack as two rows (one per ring);
- :func:`mask_overlay`: masked observations over the image, shadows green (darker than
  the Lambert prediction of the solution), highlights blue (brighter);
- :func:`normals_rgb`: normals as RGB [(nx+1)/2, (ny+1)/2, nz] (thesis Figs. 5.17, 7.8);
- :func:`shade`: shaded relief of a height map (Lambert, one oblique light);
- :func:`align`: resample a case into its sister's gun frame (the thesis matched the two
  cases' orientations "as much as possible" for Figs. 7.7-7.9); vector fields rotate too.
"""
from __future__ import annotations

import base64
import math

import cv2
import numpy as np

__all__ = ["encode", "decode", "thumb", "montage", "mask_overlay", "normals_rgb", "shade",
           "align_matrix", "align", "crop_box"]


def encode(img, fmt="png", quality=90):
    """uint8 (H, W) or (H, W, 3) RGB -> base64 text of a PNG or JPEG."""
    img = np.ascontiguousarray(img)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    params = [cv2.IMWRITE_JPEG_QUALITY, int(quality)] if fmt == "jpg" else []
    ok, buf = cv2.imencode("." + fmt, img, params)
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 image
        raise RuntimeError(f"could not encode a {img.shape} image as {fmt}")
    return base64.b64encode(buf.tobytes()).decode("ascii")


def decode(text):
    """base64 text of :func:`encode` -> uint8 (H, W) or (H, W, 3) RGB."""
    buf = np.frombuffer(base64.b64decode(text), np.uint8)
    img = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    if img is not None and img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
    return img


def to_u8(x, lo=0.0, hi=1.0):
    """Floats in [lo, hi] -> uint8 0..255 (clipped)."""
    y = (np.asarray(x, np.float32) - np.float32(lo)) / np.float32(max(hi - lo, 1e-12))
    return np.rint(np.clip(y, 0.0, 1.0) * 255.0).astype(np.uint8)


def thumb(img, side):
    """Downsample (area average) so that the longer side is at most ``side`` pixels."""
    h, w = img.shape[:2]
    f = side / max(h, w)
    if f >= 1:
        return img
    return cv2.resize(img, (max(1, round(w * f)), max(1, round(h * f))),
                      interpolation=cv2.INTER_AREA)


def crop_box(region, margin=0.05):
    """(row slice, col slice) of a region's bounding box grown by ``margin`` of its size,
    clipped to the image."""
    rr, cc = np.nonzero(region)
    H, W = region.shape
    pad = int(math.ceil(margin * max(np.ptp(rr), np.ptp(cc), 1)))
    return (slice(max(rr.min() - pad, 0), min(rr.max() + pad + 1, H)),
            slice(max(cc.min() - pad, 0), min(cc.max() + pad + 1, W)))


def montage(tiles, rows, gap=4, fill=255):
    """Tiles of equal shape in ``rows`` rows, ``gap`` pixels of ``fill`` between them."""
    tiles = list(tiles)
    cols = math.ceil(len(tiles) / rows)
    h, w = tiles[0].shape[:2]
    shape = (rows * h + (rows - 1) * gap, cols * w + (cols - 1) * gap) + tiles[0].shape[2:]
    out = np.full(shape, fill, np.uint8)
    for i, t in enumerate(tiles):
        r, c = divmod(i, cols)
        out[r * (h + gap):r * (h + gap) + h, c * (w + gap):c * (w + gap) + w] = t
    return out


def mask_overlay(image, masked, residual, object_mask):
    """RGB: the image in grey, masked observations green where the image is darker than
    the Lambert prediction (shadow) and blue where brighter (highlight); outside the
    object dark grey."""
    g = np.asarray(image, np.float32)
    hi = float(np.percentile(g[object_mask], 99.5)) if object_mask.any() else 1.0
    grey = to_u8(g, 0.0, hi) // 4 * 3
    rgb = np.repeat(grey[..., None], 3, axis=-1)
    m = np.asarray(masked, bool) & object_mask
    rgb[m & (residual < 0)] = (0, 200, 0)
    rgb[m & (residual >= 0)] = (40, 90, 255)
    rgb[~object_mask] = (40, 40, 40)
    return rgb


def normals_rgb(normals, object_mask=None):
    """Normals -> uint8 RGB [(nx+1)/2, (ny+1)/2, nz]; black outside the object."""
    n = np.asarray(normals, np.float32)
    rgb = np.stack([(n[..., 0] + 1) / 2, (n[..., 1] + 1) / 2, n[..., 2]], axis=-1)
    out = to_u8(rgb)
    if object_mask is not None:
        out[~np.asarray(object_mask, bool)] = 0
    return out


def shade(height_um, pixel_size, object_mask=None, *, azimuth=135.0, elevation=35.0,
          exaggeration=1.0, stretch=None):
    """Shaded relief (uint8): Lambert shading of the height map (heights times
    ``exaggeration``) under one distant light (``azimuth`` counter-clockwise from +x,
    display frame y up; ``elevation`` above the horizon, degrees); black outside the
    object. ``stretch``: a (H, W) bool region whose 1st-99th percentile of the shading is
    stretched to the full grey range (shallow marks become visible)."""
    z = np.asarray(height_um, np.float32) * np.float32(exaggeration / pixel_size)
    d_row, d_col = np.gradient(z)
    a, e = math.radians(azimuth), math.radians(elevation)
    light = np.float32([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    # normal (-dz/dx, -dz/dy, 1) with dz/dy = -dz/drow
    num = -d_col * light[0] + d_row * light[1] + light[2]
    s = num / np.sqrt(1.0 + d_col * d_col + d_row * d_row)
    lo, hi = 0.0, 1.0
    if stretch is not None and np.any(stretch):
        lo, hi = (float(v) for v in np.percentile(s[stretch], (1.0, 99.0)))
    out = to_u8(s, lo, hi)
    if object_mask is not None:
        out[~np.asarray(object_mask, bool)] = 0
    return out


def align_matrix(pose_to, pose_from, shape, pixel_size):
    """(2, 3) map of output pixels (col, row) in case ``pose_to``'s frame to the pixels of
    case ``pose_from`` carrying the same gun marks (for ``cv2.warpAffine`` with
    ``WARP_INVERSE_MAP``); also returns the rotation angle (radians, counter-clockwise)
    that takes ``pose_to``'s directions to ``pose_from``'s."""
    H, W = shape
    a = math.radians(pose_from["gun_angle"] - pose_to["gun_angle"])
    c, s = math.cos(a), math.sin(a)
    gt = np.array([pose_to["gun_x"], pose_to["gun_y"]]) / pixel_size
    gf = np.array([pose_from["gun_x"], pose_from["gun_y"]]) / pixel_size
    # pixel (col, row) -> centred (x, y up): x = col - cx, y = cy - row
    cx, cy = (W - 1) / 2.0, (H - 1) / 2.0
    # p_from = g_from + R(a) (p_to - g_to) in (x, y); written for (col, row)
    R = np.array([[c, -s], [s, c]])
    A = np.array([[1.0, 0.0], [0.0, -1.0]])          # (col, row) offsets <-> (x, y)
    M = A @ R @ A
    off = A @ (gf - R @ gt) + np.array([cx, cy]) - M @ np.array([cx, cy])
    return np.hstack([M, off[:, None]]), a


def align(img, pose_to, pose_from, pixel_size, *, vectors=False, nearest=False):
    """Resample ``img`` of case ``pose_from`` into case ``pose_to``'s frame (same shape);
    ``vectors``: ``img`` is (H, W, 3) normals whose (x, y) components are rotated too."""
    img = np.asarray(img)
    M, a = align_matrix(pose_to, pose_from, img.shape[:2], pixel_size)
    flags = (cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR) | cv2.WARP_INVERSE_MAP
    src = img.astype(np.float32) if not nearest else img.astype(np.uint8)
    out = cv2.warpAffine(src, M, (img.shape[1], img.shape[0]), flags=flags,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=0)
    if vectors:
        c, s = math.cos(-a), math.sin(-a)            # from_frame directions -> to_frame
        x, y = out[..., 0].copy(), out[..., 1].copy()
        out[..., 0], out[..., 1] = c * x - s * y, s * x + c * y
    return out
