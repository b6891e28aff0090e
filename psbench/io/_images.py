"""Reading and writing single images and image stacks (8/12/16-bit PNG/TIFF)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError
from .._shared.deprecation import renamed_args
from ._common import IMAGE_EXT, LUMA, cv2 as _cv2

__all__ = ["read_image", "read_images", "write_image"]


def _to_luma(arr, rgb_scale=None):
    """(H, W, C) BGR[A] -> (H, W) float64 luma. rgb_scale: (3,) per-channel divisor (RGB)."""
    bgr = arr[..., :3].astype(np.float64)
    rgb = bgr[..., ::-1]
    if rgb_scale is not None:
        rgb = rgb / rgb_scale
    return rgb @ LUMA


def _scale_of(dtype, bits, path):
    if dtype == np.uint8:
        if bits not in (None, 8):
            raise PsbenchError(f"{path}: bits={bits} given but the file holds 8-bit data")
        return 255.0
    if dtype == np.uint16:
        b = 16 if bits is None else int(bits)
        if not 9 <= b <= 16:
            raise PsbenchError(f"{path}: bits={bits} is not valid for 16-bit files (9..16)")
        return float(2 ** b - 1)
    if dtype in (np.float32, np.float64):
        return 1.0
    raise PsbenchError(f"{path}: unsupported image dtype {dtype} (expected 8/16-bit or float32)")


def read_image(path, *, bits=None, rgb_scale=None, raw=False):
    """Read one image as linear float32 (H, W) in [0, 1].

    Parameters
    ----------
    path : str or Path
    bits : int, optional
        Significant bits of 16-bit files (12 for 12-bit data in 16-bit containers);
        default: the container's depth.
    rgb_scale : (3,) array_like, optional
        Per-channel (R, G, B) divisor applied to colour images before the luma.
    raw : bool
        Return the undecoded array as stored (uint8/uint16, possibly colour).
    """
    cv2 = _cv2()
    p = Path(path)
    if not p.is_file():
        raise PsbenchError(f"image file {str(p)!r} does not exist")
    arr = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
    if arr is None:
        raise PsbenchError(f"image file {str(p)!r} could not be decoded (not a PNG/TIFF image?)")
    if raw:
        return arr
    scale = _scale_of(arr.dtype, bits, p)
    if arr.ndim == 3:
        if arr.shape[2] == 1:
            img = arr[..., 0].astype(np.float64)
        elif arr.shape[2] in (3, 4):
            img = _to_luma(arr, rgb_scale)
        else:
            raise PsbenchError(f"{p}: {arr.shape[2]} channels not supported")
    elif arr.ndim == 2:
        img = arr.astype(np.float64)
    else:
        raise PsbenchError(f"{p}: unexpected image shape {arr.shape}")
    return (img / scale).astype(np.float32)


def read_images(paths, *, bits=None, rgb_scale=None):
    """Read a stack of images of one size and bit depth.

    Parameters
    ----------
    paths : sequence of str or Path
    bits : int, optional
        See :func:`read_image`.
    rgb_scale : (k, 3) array_like, optional
        Per-image RGB divisors for colour images.

    Returns
    -------
    images : (k, H, W) float32, linear in [0, 1]
    """
    cv2 = _cv2()
    paths = [Path(p) for p in paths]
    if not paths:
        raise PsbenchError("paths is empty: no images to read")
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        more = f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""
        raise PsbenchError(f"image file {missing[0]!r} does not exist{more}")
    out = None
    ref = None
    for i, p in enumerate(paths):
        arr = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if arr is None:
            raise PsbenchError(f"image file {str(p)!r} could not be decoded (not a PNG/TIFF image?)")
        if ref is None:
            ref = (arr.shape[:2], arr.dtype, p)
            out = np.empty((len(paths),) + arr.shape[:2], dtype=np.float32)
        else:
            if arr.shape[:2] != ref[0]:
                raise PsbenchError(
                    f"images differ in size: {str(ref[2])!r} is {ref[0][1]}x{ref[0][0]} (WxH) "
                    f"but {str(p)!r} is {arr.shape[1]}x{arr.shape[0]}")
            if arr.dtype != ref[1]:
                raise PsbenchError(
                    f"images differ in bit depth: {str(ref[2])!r} is {ref[1]} "
                    f"but {str(p)!r} is {arr.dtype}")
        scale = _scale_of(arr.dtype, bits, p)
        rs = None if rgb_scale is None else np.asarray(rgb_scale, dtype=np.float64)[i]
        if arr.ndim == 3 and arr.shape[2] in (3, 4):
            out[i] = _to_luma(arr, rs) / scale
        elif arr.ndim == 3:
            out[i] = arr[..., 0] / scale
        else:
            out[i] = arr / scale
    return out


@renamed_args(positional=("bits",))
def write_image(path, img, *, bits=16):
    """Write a float image in [0, 1] (or an integer image as is) to PNG/TIFF.

    Parameters
    ----------
    path : str or Path
        ``.png``, ``.tif`` or ``.tiff``.
    img : (H, W) or (H, W, 3) array
        Float data are clipped to [0, 1] and rounded to ``bits`` (8, 12 or 16;
        12-bit data are stored in a 16-bit container with codes 0..4095).
        Colour arrays are RGB (converted to OpenCV's BGR order here).
        Unsigned integer arrays are written unchanged.
    """
    cv2 = _cv2()
    p = Path(path)
    if p.suffix.lower() not in IMAGE_EXT:
        raise PsbenchError(f"path {str(p)!r}: expected a .png/.tif/.tiff file name")
    a = np.asarray(img)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] != 3):
        raise PsbenchError(f"img must have shape (H, W) or (H, W, 3), got {a.shape}")
    if np.issubdtype(a.dtype, np.unsignedinteger):
        if a.dtype not in (np.uint8, np.uint16):
            raise PsbenchError(f"img dtype {a.dtype}: only uint8/uint16 can be written")
        data = a
    else:
        if bits not in (8, 12, 16):
            raise PsbenchError(f"bits must be 8, 12 or 16, got {bits!r}")
        a = np.asarray(a, dtype=np.float64)
        if not np.isfinite(a).all():
            raise PsbenchError(f"img holds NaN/inf values; cannot write {str(p)!r}")
        q = np.round(np.clip(a, 0.0, 1.0) * (2 ** bits - 1))
        data = q.astype(np.uint8 if bits == 8 else np.uint16)
    if data.ndim == 3:
        data = np.ascontiguousarray(data[..., ::-1])
    p.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(p), data):
        raise PsbenchError(f"could not write image {str(p)!r}")
