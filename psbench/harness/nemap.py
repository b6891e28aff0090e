"""The ``ne_map`` run extra: a small per-pixel angular-error map stored in the results row.

The map is the angular error (deg) over the object, reduced so that its longer side is at
most :data:`MAX_SIDE` pixels (area means over the object's pixels only, so the border
does not mix in the background), quantised to centi-degrees (uint16, clipped at
:data:`CLIP` deg), PNG-encoded and stored as base64 text. Pixels outside the object hold
:data:`OUTSIDE`. :func:`decode` gives it back as float32 degrees with NaN outside.
"""
from __future__ import annotations

import base64

import numpy as np

__all__ = ["MAX_SIDE", "CLIP", "OUTSIDE", "encode", "decode"]

MAX_SIDE = 160          # px: longer side of the stored map
CLIP = 90.0             # deg: larger errors are stored as CLIP
OUTSIDE = 65535         # uint16 code of pixels outside the object


def encode(error, object_mask=None) -> str:
    """Base64 PNG text of an angular-error map.

    Parameters
    ----------
    error : (H, W) array_like
        Angular error in degrees (NaN allowed: treated as outside).
    object_mask : (H, W) bool, optional
        The object; None = every finite pixel.

    Returns
    -------
    str
        A 16-bit grey PNG, at most :data:`MAX_SIDE` px on its longer side, base64.
    """
    from ..io._common import cv2 as _cv2

    cv2 = _cv2()
    e = np.asarray(error, dtype=np.float32)
    inside = np.isfinite(e)
    if object_mask is not None:
        inside &= np.asarray(object_mask, bool)
    H, W = e.shape
    f = min(1.0, MAX_SIDE / max(H, W))
    if f < 1.0:
        size = (max(1, round(W * f)), max(1, round(H * f)))
        m = inside.astype(np.float32)
        # mean error over the object's pixels of each area: resize(e*m) / resize(m)
        num = cv2.resize(np.where(inside, e, 0).astype(np.float32), size,
                         interpolation=cv2.INTER_AREA)
        den = cv2.resize(m, size, interpolation=cv2.INTER_AREA)
        inside = den >= 0.5
        e = num / np.maximum(den, 1e-6)
    q = np.round(np.clip(np.where(inside, e, 0), 0, CLIP) * 100).astype(np.uint16)
    q[~inside] = OUTSIDE
    ok, buf = cv2.imencode(".png", q)
    if not ok:
        raise RuntimeError("PNG encoding of the ne_map failed")
    return base64.b64encode(buf.tobytes()).decode("ascii")


def decode(text) -> np.ndarray | None:
    """(H, W) float32 degrees with NaN outside the object; None for a missing map
    (None, NaN or empty text, as older rows hold)."""
    if not isinstance(text, str) or not text:
        return None
    from ..io._common import cv2 as _cv2

    cv2 = _cv2()
    buf = np.frombuffer(base64.b64decode(text), dtype=np.uint8)
    q = cv2.imdecode(buf, cv2.IMREAD_UNCHANGED)
    if q is None or q.dtype != np.uint16 or q.ndim != 2:
        raise ValueError("ne_map is not a 16-bit grey PNG")
    out = q.astype(np.float32) / 100
    out[q == OUTSIDE] = np.nan
    return out
