"""Dynamic ranges of the images, shared by the range-based masks (Th, NL, CS, Hi) and
the weighted steps.

**Range scope** (``th_scope``): "image" (thesis: min/max of each whole image),
"object" (min/max over the object mask), "robust" (1st-99th percentile over the
object, so one specular spot does not set the range), "pixel" (albedo-invariant:
the lower Th bound, Hi and CS use the pixel's brightest observation over the k
images as range with i_min = 0; the upper Th bound keeps the "robust" image range,
because k_up = 0.35 of a pixel's own maximum would mask most diffuse
observations, and highlights are additive rather than scaled by the diffuse
albedo).
"""
from __future__ import annotations

import numpy as np

from ..._shared.checks import PsbenchError

__all__ = ["SCOPES", "ranges"]

SCOPES = ("image", "object", "robust", "pixel")


def ranges(images, *, scope="image", object_mask=None, offset=False):
    """Dynamic ranges used by Th, Hi, CS (and NL scaling).

    Parameters
    ----------
    images : (k, H, W) float32
    scope : {"image", "object", "robust", "pixel"}
    object_mask : (H, W) bool, optional
    offset : bool
        Offset the Th bounds by i_min (True) or not (False, literal Eq. 3.2, default).

    Returns
    -------
    dict with
        ``lo`` (k, 1, 1) or (1, H, W): i_min used as offset for Th (0 if not offset),
        ``rng`` (k, 1, 1) or (1, H, W): range for the lower Th bound, Hi and CS,
        ``lo_up``, ``rng_up`` (k, 1, 1): offset and range for the upper Th bound,
        ``scale`` float: mean image range (NL scaling, > 0),
        ``dead`` (k, 1, 1) bool: images with zero range; Th, Hi and CS never mask
        them (a constant image carries no range to be a fraction of).
    """
    k = images.shape[0]
    flat = images.reshape(k, -1)
    m = None if object_mask is None or object_mask.all() else object_mask.reshape(-1)
    if scope == "image":
        imin, imax = flat.min(axis=1), flat.max(axis=1)
    elif scope == "object":
        sel = flat if m is None else flat[:, m]
        imin, imax = _minmax(sel)
    elif scope in ("robust", "pixel"):
        sel = flat if m is None else flat[:, m]
        imin, imax = _percentiles(sel)
    else:
        raise PsbenchError(f"th_scope={scope!r} is not known; valid choices: {', '.join(SCOPES)}")
    imin = imin.astype(np.float32)
    rng_img = np.maximum(imax.astype(np.float32) - imin, 0.0)
    lo_img = imin if offset else np.zeros_like(imin)
    out = {"lo_up": lo_img.reshape(k, 1, 1), "rng_up": rng_img.reshape(k, 1, 1)}
    if scope == "pixel":
        pmax = images.max(axis=0, keepdims=True)
        out["lo"] = np.zeros((1, 1, 1), dtype=np.float32)
        out["rng"] = pmax
    else:
        out["lo"], out["rng"] = out["lo_up"], out["rng_up"]
    scale = float(rng_img.mean())
    out["scale"] = scale if scale > 0 else 1.0
    out["dead"] = (rng_img <= 0).reshape(k, 1, 1)  # zero-range images: masks keep them
    return out


def _minmax(sel):
    if sel.shape[1] == 0:
        z = np.zeros(sel.shape[0], dtype=np.float32)
        return z, z
    return sel.min(axis=1), sel.max(axis=1)


def _percentiles(sel, q=(1.0, 99.0), max_samples=1 << 16):
    """1st and 99th percentiles per image (on a regular subsample for speed)."""
    if sel.shape[1] == 0:
        z = np.zeros(sel.shape[0], dtype=np.float32)
        return z, z
    step = max(1, sel.shape[1] // max_samples)
    p = np.percentile(sel[:, ::step], q, axis=1)
    return p[0], p[1]
