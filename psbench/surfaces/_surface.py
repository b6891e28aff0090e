"""The :class:`Surface` type and the pixel-grid helpers every surface family shares."""
from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from .._shared.checks import PsbenchError, as_mask
from .._shared.deprecation import warn_renamed

__all__ = ["Surface", "pixel_grid", "normals_from_height", "MIN_SIZE"]

#: smallest side accepted by :func:`psbench.make_surface`
MIN_SIZE = 16


@dataclass(frozen=True, eq=False, init=False)
class Surface:
    """A height field with its object mask and unit normals.

    Parameters
    ----------
    name : str
        Surface name.
    height : (H, W) array_like
        Heights in pixel units (+z towards the camera). Outside the object mask the
        height is the background the object sits on (0 for the named surfaces).
    object_mask : (H, W) bool array_like
        True where the surface is part of the object under test.
    normals : (H, W, 3) array_like
        Unit normals ``(nx, ny, nz)`` in the psbench frame (x right, y up, camera
        at +z). Outside the object mask they are ``(0, 0, 1)``.

    Attributes
    ----------
    name : str
    height : (H, W) float32
    object_mask : (H, W) bool
    normals : (H, W, 3) float32

    The arrays are stored read-only; copy them before modifying. ``mask`` is the
    deprecated name of ``object_mask`` (argument and attribute).
    """

    name: str
    height: np.ndarray
    object_mask: np.ndarray
    normals: np.ndarray

    def __init__(self, name, height, object_mask=None, normals=None, *, mask=None):
        if mask is not None:
            if object_mask is not None:
                raise TypeError("Surface() got both mask= (deprecated) and object_mask=")
            warn_renamed("Surface(mask=...)", "object_mask=...")
            object_mask = mask
        if object_mask is None or normals is None:
            raise TypeError("Surface() needs name, height, object_mask and normals")
        height = np.array(height, dtype=np.float32, copy=True)
        if height.ndim != 2:
            raise PsbenchError(f"height must have shape (H, W), got {height.shape}")
        object_mask = np.array(as_mask(object_mask, height.shape, "object_mask"), dtype=bool,
                               copy=True)
        normals = np.array(normals, dtype=np.float32, copy=True)
        if normals.shape != height.shape + (3,):
            raise PsbenchError(
                f"normals must have shape {height.shape + (3,)}, got {normals.shape}")
        if not (np.isfinite(height).all() and np.isfinite(normals).all()):
            raise PsbenchError("height and normals must be finite")
        for arr in (height, object_mask, normals):
            arr.setflags(write=False)
        self._set(str(name), height, object_mask, normals)

    def _set(self, name, height, object_mask, normals):
        for key, value in (("name", name), ("height", height), ("object_mask", object_mask),
                           ("normals", normals)):
            object.__setattr__(self, key, value)

    def renamed(self, name):
        """The same surface (arrays shared, not copied) under another name; a subclass
        (a cartridge case with its pixel size and ground truth) keeps its type and fields."""
        out = copy.copy(self)
        object.__setattr__(out, "name", str(name))
        return out

    @property
    def mask(self):
        """Deprecated name of :attr:`object_mask`."""
        warn_renamed("Surface.mask", "Surface.object_mask")
        return self.object_mask

    @property
    def shape(self):
        """(H, W) of the height map."""
        return self.height.shape

    @property
    def zenith(self):
        """(H, W) float32: surface zenith in degrees, the angle between the normal and +z."""
        nz = np.clip(self.normals[..., 2], -1.0, 1.0)
        return np.degrees(np.arccos(nz)).astype(np.float32)

    def __repr__(self):
        m = self.object_mask
        h = self.height[m] if m.any() else self.height
        return (f"Surface(name={self.name!r}, shape={self.shape}, "
                f"object_mask={int(m.sum())} px, height=[{h.min():.3g}, {h.max():.3g}] px, "
                f"max zenith={float(self.zenith[m].max()) if m.any() else 0:.1f} deg)")


# --------------------------------------------------------------------------- helpers
def pixel_grid(shape):
    """Pixel-centre coordinates in the psbench frame.

    Parameters
    ----------
    shape : (H, W)

    Returns
    -------
    x : (1, W) float64
        ``c - (W - 1) / 2`` (x to the right).
    y : (H, 1) float64
        ``(H - 1) / 2 - r`` (y up). ``x`` and ``y`` broadcast to (H, W).
    """
    h, w = int(shape[0]), int(shape[1])
    x = (np.arange(w, dtype=np.float64) - (w - 1) / 2.0)[None, :]
    y = ((h - 1) / 2.0 - np.arange(h, dtype=np.float64))[:, None]
    return x, y


def normals_from_slopes(p, q):
    """Unit normals from slopes p = dz/dx, q = dz/dy -> (H, W, 3) float32."""
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    p, q = np.broadcast_arrays(p, q)
    inv = 1.0 / np.sqrt(1.0 + p * p + q * q)
    out = np.empty(p.shape + (3,), dtype=np.float32)
    out[..., 0] = -p * inv
    out[..., 1] = -q * inv
    out[..., 2] = inv
    return out


def normals_from_height(height):
    """Unit normals of a height map by central differences (``np.gradient``).

    Parameters
    ----------
    height : (H, W) array_like
        Heights in pixel units, H, W >= 2.

    Returns
    -------
    normals : (H, W, 3) float32
        ``n ∝ (-dz/dx, -dz/dy, 1)`` with ``dz/dx = d/dcol`` and
        ``dz/dy = -d/drow`` (y up). One-sided differences on the border.
    """
    z = np.asarray(height, dtype=np.float64)
    d_row, d_col = np.gradient(z)
    return normals_from_slopes(d_col, -d_row)


def finish(name, height, object_mask, normals):
    """Build a Surface with normals (0, 0, 1) outside the object mask."""
    normals = np.asarray(normals, dtype=np.float32)
    if not object_mask.all():
        normals = normals.copy()
        normals[~object_mask] = (0.0, 0.0, 1.0)
    return Surface(name, height.astype(np.float32), object_mask, normals)


def check_size(size):
    """``size`` as an int >= :data:`MIN_SIZE`, else a :class:`PsbenchError`."""
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)):
        raise PsbenchError(f"size must be an integer >= {MIN_SIZE}, got {size!r}")
    if size < MIN_SIZE:
        raise PsbenchError(f"size must be an integer >= {MIN_SIZE}, got {size}")
    return int(size)


# --------------------------------------------------------------------------- shapes
def smax(a, b, k):
    """Smooth maximum of a and b (log-sum-exp with sharpness k, in height units)."""
    m = np.maximum(a, b)
    return m + np.log(np.exp(k * (a - m)) + np.exp(k * (b - m))) / k


def gauss(u, v, u0, v0, su, sv):
    """Separable axis-aligned Gaussian exp(-(du²/2su² + dv²/2sv²)) as an outer product."""
    return np.exp(-0.5 * ((v - v0) / sv) ** 2) * np.exp(-0.5 * ((u - u0) / su) ** 2)


def dome(u, v, u0, v0, a, b, c, power=0.5):
    """Ellipsoid-like dome c * (1 - q)^power inside the ellipse q < 1, else 0."""
    q = ((v - v0) / b) ** 2 + ((u - u0) / a) ** 2
    return c * np.maximum(1.0 - q, 0.0) ** power
