"""Building surfaces: named ones from the registry, user height maps from arrays or files."""
from __future__ import annotations

import inspect
import math
from pathlib import Path

import numpy as np

from .. import registry
from .._shared.checks import PsbenchError, as_mask
from .._shared.deprecation import renamed_args
from ._surface import Surface, check_size, finish, normals_from_height
from ._topography import read_topography, surface_from_topography

__all__ = ["make_surface", "surface_from_height", "surface_from_file"]


def _accepted(func):
    """Keyword options a generator takes besides ``size`` (None: any, it has **kw)."""
    try:
        params = inspect.signature(func).parameters
    except (TypeError, ValueError):  # builtins or C callables: let them decide
        return None
    if any(p.kind is p.VAR_KEYWORD for p in params.values()):
        return None
    return [n for n, p in list(params.items())[1:]
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]


@renamed_args(positional=("size",))
def make_surface(name, *, size=512, **kwargs):
    """Make a named test surface.

    Parameters
    ----------
    name : str
        A registered surface (case-insensitive): psbench's own ``semisphere``,
        ``spheres``, ``sombrero`` (= ``sombrero2``), ``sombrero1``, ``sombrero2``,
        ``sombrero3``, ``mozart``, ``penny``, and any surface a plug-in registers
        (:data:`psbench.SURFACES` lists them all).
    size : int, default 512
        Side of the square (size, size) grid, >= 16. Shapes scale with the size:
        heights are in pixel units, so slopes and zeniths do not depend on it (up to
        sampling).
    **kwargs
        Options of the surface's generator (psbench's own surfaces take none; a
        plug-in documents its own, e.g. a cartridge case's ``gun=``, ``case=``).

    Returns
    -------
    Surface
        ``.height (size, size) float32``, ``.object_mask (size, size) bool``,
        ``.normals (size, size, 3) float32``; deterministic. Named as asked (an
        alias keeps its own name).
    """
    if not isinstance(name, str):
        raise PsbenchError(f"name must be a surface name (str), got {name!r}; valid choices: "
                           f"{', '.join(registry.names('surfaces'))}")
    spec = registry.get("surfaces", name, what="name")
    size = check_size(size)
    accepted = _accepted(spec.func)
    if accepted is not None:
        bad = sorted(set(kwargs) - set(accepted))
        if bad:
            valid = ", ".join(accepted) if accepted else "none"
            raise PsbenchError(f"surface {spec.name!r} takes no option {bad[0]!r}; "
                               f"its options: {valid}")
    surf = spec.func(size, **kwargs)
    if not isinstance(surf, Surface):
        raise PsbenchError(f"surface {spec.name!r}: its generator returned "
                           f"{type(surf).__name__}, expected psbench.Surface")
    asked = next((a for a in (spec.name, *spec.aliases) if a.lower() == name.lower()),
                 spec.name)
    return surf if surf.name == asked else surf.renamed(asked)


@renamed_args(positional=("object_mask", "name"), renamed={"mask": "object_mask"})
def surface_from_height(height, *, object_mask=None, name="custom"):
    """Wrap any height map as a :class:`Surface` (normals by central differences).

    Parameters
    ----------
    height : (H, W) array_like of float or int
        Finite heights in pixel units, H, W >= 2.
    object_mask : (H, W) bool array_like, optional
        Object region; default all True. Outside it the normals are set to
        (0, 0, 1); the heights are kept as given (they are the background the
        object sits on, and they enter the central differences at its border).
    name : str, default "custom"

    Returns
    -------
    Surface
    """
    arr = np.asarray(height)
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.integer)
                                 or np.issubdtype(arr.dtype, np.floating)):
        raise PsbenchError(f"height must be a float or integer array, got dtype {arr.dtype}")
    if arr.ndim != 2:
        raise PsbenchError(f"height must have shape (H, W), got shape {arr.shape}")
    if arr.shape[0] < 2 or arr.shape[1] < 2:
        raise PsbenchError(f"height must be at least 2 x 2, got shape {arr.shape}")
    z = arr.astype(np.float64)
    if not np.isfinite(z).all():
        bad = int((~np.isfinite(z)).sum())
        raise PsbenchError(f"height holds {bad} NaN/inf values; fill or crop them first")
    m = as_mask(object_mask, z.shape, "object_mask")
    return finish(str(name), z, np.asarray(m, dtype=bool), normals_from_height(z))


@renamed_args(renamed={"mask": "object_mask"})
def surface_from_file(path, *, scale=None, object_mask=None, name=None):
    """Read a height map from ``.npy``, 16-bit ``.png`` or ``.x3p`` into a :class:`Surface`.

    Parameters
    ----------
    path : str or Path
        ``.npy``: a 2-D numeric array of heights in pixel units, multiplied by
        ``scale`` (default 1).
        ``.png``: a single-channel 16-bit (or 8-bit) image read with OpenCV
        (``cv2.IMREAD_UNCHANGED``). A value ``v`` maps to the height
        ``v / vmax * scale`` pixels, where ``vmax`` is 65535 (255 for 8-bit)
        and ``scale`` defaults to ``width / 4``: the full 16-bit range spans a
        quarter of the image width.
        ``.x3p``: an ISO 25178-72 surface (:func:`psbench.io.read_x3p`); heights in µm
        divided by the file's pixel size in µm give pixel units (times ``scale``, default
        1); the file's valid points are the object mask (invalid points take their
        nearest valid neighbour's height).
    scale : float, optional
        See above.
    object_mask : (H, W) bool array_like, optional
        Object region (default all True; for ``.x3p`` it is ANDed with the valid points).
    name : str, optional
        Default: the file's stem.

    Returns
    -------
    Surface
    """
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in (".npy", ".png", ".x3p"):
        raise PsbenchError(f"path must end in .npy, .png or .x3p, got {str(path)!r}")
    if not p.is_file():
        raise PsbenchError(f"path {str(path)!r} does not exist or is not a file")
    if scale is not None:
        scale = float(scale)
        if not math.isfinite(scale) or scale <= 0:
            raise PsbenchError(f"scale must be a positive finite number, got {scale}")
    if ext == ".x3p":
        return surface_from_topography(read_topography(p), object_mask=object_mask,
                                       scale=1.0 if scale is None else scale,
                                       name=p.stem if name is None else name)
    if ext == ".npy":
        try:
            arr = np.load(p, allow_pickle=False)
        except Exception as exc:  # noqa: BLE001 - report any reader failure clearly
            raise PsbenchError(f"path {str(path)!r} is not a readable .npy array: {exc}") from exc
        if arr.dtype == bool or not np.issubdtype(arr.dtype, np.number):
            raise PsbenchError(f"{p.name} must hold a numeric array, got dtype {arr.dtype}")
        height = arr.astype(np.float64) * (1.0 if scale is None else scale)
    else:
        import cv2

        img = cv2.imread(str(p), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise PsbenchError(f"path {str(path)!r} is not a readable PNG")
        if img.ndim == 3:
            if img.shape[2] >= 3 and np.array_equal(img[..., 0], img[..., 1]) \
                    and np.array_equal(img[..., 1], img[..., 2]):
                img = img[..., 0]
            else:
                raise PsbenchError(f"{p.name} must be a single-channel (grey) height PNG, "
                                   f"got {img.shape[2]} channels")
        if img.dtype not in (np.uint16, np.uint8):
            raise PsbenchError(f"{p.name} must be a 16-bit (or 8-bit) PNG, got dtype {img.dtype}")
        vmax = float(np.iinfo(img.dtype).max)
        full = img.shape[1] / 4.0 if scale is None else scale
        height = img.astype(np.float64) / vmax * full
    return surface_from_height(height, object_mask=object_mask,
                               name=p.stem if name is None else name)
