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


def workers(value, name="jobs"):
    """Refuse a worker or thread count that is not a whole number >= 1 or -1 (one per
    core)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not (
            value == -1 or value >= 1):
        raise PsbenchError(f"{name} must be a whole number >= 1, or -1 (one per core), got "
                           f"{value!r}")
    return int(value)


def as_images(images, name="images", *, min_count=1):
    """Validate an image stack and return it as C-contiguous float32 (k, H, W).

    Integer images are converted explicitly: unsigned integers are divided by the
    largest value of their dtype (8-bit -> /255, 16-bit -> /65535) to linear [0, 1];
    booleans are refused. A single (H, W) image is refused: pass a stack. Images must
    be linear intensities: a stack whose mean is negative (negated images) is refused;
    small negative values (noise, ``shadows="none"`` renderings) are accepted.
    """
    try:
        arr = np.asarray(images)
    except (ValueError, TypeError) as exc:   # ragged lists of images
        raise PsbenchError(f"{name} must be a (k, H, W) array of equal-size images; got "
                           f"{type(images).__name__} that numpy cannot stack ({exc})") from None
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.number)):
        raise PsbenchError(f"{name} must be a numeric array, got dtype {arr.dtype}")
    if arr.ndim != 3:
        raise PsbenchError(f"{name} must have shape (k, H, W), got shape {arr.shape}")
    if arr.shape[0] < min_count:
        raise PsbenchError(f"{name} must hold at least {min_count} images, got {arr.shape[0]}")
    if arr.shape[1] < 1 or arr.shape[2] < 1:
        raise PsbenchError(f"{name} must hold at least one pixel per image, got shape {arr.shape}")
    if np.issubdtype(arr.dtype, np.unsignedinteger):
        arr = arr.astype(np.float32) / np.float32(np.iinfo(arr.dtype).max)
    elif np.issubdtype(arr.dtype, np.integer):
        raise PsbenchError(f"{name} has signed integer dtype {arr.dtype}; pass float or unsigned images")
    elif np.issubdtype(arr.dtype, np.complexfloating):
        raise PsbenchError(f"{name} must be real, got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.float32)
    with np.errstate(over="ignore", invalid="ignore"):
        total = float(arr.sum())       # one pass: NaN / inf propagate into the sum
    if not np.isfinite(total):         # (or a float32 overflow of huge finite values)
        finite = np.isfinite(arr)
        if not finite.all():
            bad = int((~finite).sum())
            raise PsbenchError(f"{name} holds {bad} NaN/inf pixels; clean or mask them first")
        total = float(arr.sum(dtype=np.float64))
    if total < 0:
        raise PsbenchError(f"{name} must be linear intensities >= 0, but their mean is "
                           f"{total / arr.size:.3g} < 0 (negated images?); small negative "
                           "values from noise are accepted, a negative stack is not")
    return arr


def as_mask(region, shape, name="object_mask"):
    """Return ``region`` as a bool (H, W) array; None means all True.

    ``region`` is a pixel region (an object mask, a validity map), ``name`` the
    argument it came from, named in the error. Accepts bool arrays and numeric arrays
    holding only 0 and 1; anything else (fractions, NaN, 255, strings) is refused
    rather than guessed.
    """
    if region is None:
        return np.ones(shape, dtype=bool)
    m = np.asarray(region)
    if m.shape != tuple(shape):
        raise PsbenchError(f"{name} must have shape {tuple(shape)}, got {m.shape}")
    if m.dtype == bool:
        return m
    if not np.issubdtype(m.dtype, np.number) or np.issubdtype(m.dtype, np.complexfloating):
        raise PsbenchError(f"{name} must be a bool array (or 0/1 numbers), got dtype {m.dtype}")
    with np.errstate(invalid="ignore"):
        binary = (m == 0) | (m == 1)
    if not binary.all():
        odd = np.unique(m[~binary])[:3]
        raise PsbenchError(f"{name} must be bool or hold only 0 and 1, got {m.dtype} values "
                           f"such as {', '.join(f'{v:g}' for v in odd)}; threshold it first "
                           f"(e.g. {name}=m > 0)")
    return m.astype(bool)


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
