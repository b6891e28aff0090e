"""Validation helpers used at psbench's public boundaries.

Every check raises :class:`PsbenchError` (a ``ValueError``) whose message names
the argument and states what was expected and what was given.
"""
from __future__ import annotations

import numpy as np


class PsbenchError(ValueError):
    """Bad input to a psbench function; the message names the argument."""


def choice(value, valid, name):
    """Return ``value`` if it is one of ``valid`` else raise, listing the choices."""
    if value not in valid:
        raise PsbenchError(
            f"{name}={value!r} is not known; valid choices: {', '.join(map(str, valid))}")
    return value


def as_images(images, name="images", *, min_count=1):
    """Validate an image stack and return it as C-contiguous float32 (k, H, W).

    Integer images are converted explicitly: unsigned integers are divided by the
    largest value of their dtype (8-bit -> /255, 16-bit -> /65535) to linear [0, 1];
    booleans are refused. A single (H, W) image is refused: pass a stack.
    """
    arr = np.asarray(images)
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.number)):
        raise PsbenchError(f"{name} must be a numeric array, got dtype {arr.dtype}")
    if arr.ndim != 3:
        raise PsbenchError(f"{name} must have shape (k, H, W), got shape {arr.shape}")
    if arr.shape[0] < min_count:
        raise PsbenchError(f"{name} must hold at least {min_count} images, got {arr.shape[0]}")
    if np.issubdtype(arr.dtype, np.unsignedinteger):
        arr = arr.astype(np.float32) / np.float32(np.iinfo(arr.dtype).max)
    elif np.issubdtype(arr.dtype, np.integer):
        raise PsbenchError(f"{name} has signed integer dtype {arr.dtype}; pass float or unsigned images")
    elif np.issubdtype(arr.dtype, np.complexfloating):
        raise PsbenchError(f"{name} must be real, got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.float32)
    if not np.isfinite(arr).all():
        bad = int((~np.isfinite(arr)).sum())
        raise PsbenchError(f"{name} holds {bad} NaN/inf pixels; clean or mask them first")
    return arr


def as_mask(mask, shape, name="object_mask"):
    """Return a bool (H, W) mask; None means all True."""
    if mask is None:
        return np.ones(shape, dtype=bool)
    m = np.asarray(mask)
    if m.shape != tuple(shape):
        raise PsbenchError(f"{name} must have shape {tuple(shape)}, got {m.shape}")
    return m.astype(bool, copy=False)


def as_normals(normals, name="normals", shape=None):
    n = np.asarray(normals, dtype=np.float32)
    if n.ndim != 3 or n.shape[2] != 3:
        raise PsbenchError(f"{name} must have shape (H, W, 3), got {n.shape}")
    if shape is not None and n.shape[:2] != tuple(shape):
        raise PsbenchError(f"{name} must have shape {tuple(shape) + (3,)}, got {n.shape}")
    if not np.isfinite(n).all():
        raise PsbenchError(f"{name} holds NaN/inf values")
    return n


def as_S(lights, k=None, name="lights"):
    """(k, 3) float64 illumination matrix from a Layout (its ``.S``) or an array.

    ``k``, when given, is the number of images the lights must match.
    """
    S = getattr(lights, "S", lights)
    S = np.asarray(S, dtype=np.float64)
    if S.ndim != 2 or S.shape[1] != 3:
        raise PsbenchError(f"{name} must be a Layout or a (k, 3) array, got shape {S.shape}")
    if k is not None and S.shape[0] != k:
        raise PsbenchError(f"{name} has {S.shape[0]} lights but images has {k} images")
    if not np.isfinite(S).all():
        raise PsbenchError(f"{name} holds NaN/inf values")
    return S
