"""Measured topographies: the :class:`Topography` type, reading X3P files, and surfaces from them.

An X3P file (ISO 25178-72) stores a surface as a matrix of heights in metres on a grid of
given increments (metres per pixel). psbench reads it through the maintained ``x3pio``
package (the format is never parsed here) into a :class:`Topography`: heights in µm, the
valid points, the pixel size in µm and the file's metadata. :func:`surface_from_topography`
turns one into a :class:`~psbench.surfaces.Surface` (heights in pixel units), so a scan
works wherever a surface does. :func:`psbench.io.read_x3p` and :func:`psbench.io.write_x3p`
are the public readers and writers; this module sits in the surfaces layer so that
:func:`psbench.surface_from_file` can read ``.x3p`` files without importing :mod:`psbench.io`.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError, as_mask
from ._surface import finish, normals_from_height

__all__ = ["Topography", "read_topography", "surface_from_topography", "MAX_INCREMENT_M"]

#: largest lateral increment (metres per pixel) taken as metres: a value above 1 mm per
#: pixel in a micro-topography file is the pixel size written in µm (real files do this)
MAX_INCREMENT_M = 1e-3
#: largest height span relative to the scan's lateral extent taken as metres: a surface
#: ten times taller than it is wide is heights written in µm, not a topography
MAX_HEIGHT_ASPECT = 10.0


@dataclass(frozen=True, eq=False)
class Topography:
    """A measured surface topography (one X3P surface).

    Parameters
    ----------
    height : (H, W) float32
        Heights in µm, NaN where not valid. Row 0 is the file's first stored row.
    valid : (H, W) bool
        True where the point was measured (not NaN and not marked invalid by the file's
        validity mask, ``bindata/valid.bin``). Built in memory: None means the finite
        heights, and NaN heights are never valid.
    pixel_size : float
        Lateral sampling interval in µm (the file's x and y increments, which are equal).
    meta : dict
        The file's metadata (``Record2``), keys ``date``, ``calibration_date`` (ISO 8601
        strings or None), ``creator``, ``comment`` (str or None), ``instrument`` (dict of
        ``manufacturer``, ``model``, ``serial``, ``version``), ``probing_type``
        (``"Contacting"``, ``"NonContacting"``, ``"Software"`` or None) and
        ``probing_identification``; empty when the file has none. These are exactly the
        keyword arguments :func:`psbench.io.write_x3p` accepts.
    name : str
        The file's stem ("" for a topography built in memory).
    """

    height: np.ndarray
    valid: np.ndarray
    pixel_size: float
    meta: dict = field(default_factory=dict)
    name: str = ""

    def __post_init__(self):
        h = np.asarray(self.height, dtype=np.float32)
        if h.ndim != 2:
            raise PsbenchError(f"height must have shape (H, W), got shape {h.shape}")
        v = np.asarray(as_mask(self.valid, h.shape, "valid"), dtype=bool)
        try:
            px = float(self.pixel_size)
        except (TypeError, ValueError):
            px = float("nan")
        if not math.isfinite(px) or px <= 0:
            raise PsbenchError(f"pixel_size must be a positive number of um, got "
                               f"{self.pixel_size!r}")
        object.__setattr__(self, "height", h)
        object.__setattr__(self, "valid", v & np.isfinite(h))
        object.__setattr__(self, "pixel_size", px)
        object.__setattr__(self, "meta", dict(self.meta or {}))

    @property
    def shape(self):
        """(H, W) of the height map."""
        return self.height.shape

    def __repr__(self):
        v = self.height[self.valid]
        rng = f"[{v.min():.3g}, {v.max():.3g}] um" if v.size else "no valid points"
        return (f"Topography(name={self.name!r}, shape={self.shape}, "
                f"pixel_size={self.pixel_size:.4g} um, valid={self.valid.mean():.1%}, "
                f"height={rng})")


def _date(value):
    return None if value is None else value.isoformat()


def _meta(metadata):
    """x3pio's ``Metadata`` (or None) -> a plain dict of the fields psbench keeps."""
    if metadata is None:
        return {}
    inst = metadata.instrument
    probing = metadata.probing_system
    return {"date": _date(metadata.date), "calibration_date": _date(metadata.calibration_date),
            "creator": metadata.creator, "comment": metadata.comment,
            "instrument": {"manufacturer": inst.manufacturer, "model": inst.model,
                           "serial": inst.serial, "version": inst.version},
            "probing_type": None if probing.type is None else str(probing.type.value),
            "probing_identification": probing.identification}


def read_topography(path):
    """Read an X3P surface file into a :class:`Topography` (see :func:`psbench.io.read_x3p`).

    Parameters
    ----------
    path : str or Path
        An ``.x3p`` file holding one surface layer on a regular grid.

    Returns
    -------
    Topography

    Raises
    ------
    PsbenchError
        One line naming the file and what was expected: not a file, not a ZIP/X3P
        container, a wrong MD5 checksum, a missing ``bindata`` file, a profile or a point
        cloud instead of a surface, several layers, an irregular grid, unequal x and y
        increments, or increments (or heights) evidently written in µm instead of metres.
    """
    import x3pio

    p = Path(path)
    if not p.is_file():
        raise PsbenchError(f"path {str(path)!r} does not exist or is not a file")
    what = "an ISO 25178-72 X3P surface file"
    try:
        with warnings.catch_warnings():  # x3pio multiplies NaN points by the increment
            warnings.simplefilter("ignore", RuntimeWarning)
            x3p = x3pio.read(p)
    except x3pio.X3pChecksumError as exc:
        raise PsbenchError(f"{p}: {exc} (the file was changed or damaged after it was "
                           f"written; expected {what} with matching MD5 checksums)") from None
    except x3pio.X3pFormatError as exc:
        raise PsbenchError(f"{p}: {exc}; expected {what} (a ZIP holding main.xml and "
                           f"bindata/)") from None
    if not isinstance(x3p, x3pio.Surface):
        kind = {"Profile": "a profile (one line of points)",
                "PointCloud": "a point cloud (unordered points)"}.get(type(x3p).__name__,
                                                                      type(x3p).__name__)
        raise PsbenchError(f"{p}: holds {kind}; expected {what} (a matrix of heights)")
    if len(x3p.layers) != 1:
        raise PsbenchError(f"{p}: holds {len(x3p.layers)} surface layers; expected {what} "
                           f"with one layer")
    if not x3p.is_regular_grid:
        raise PsbenchError(f"{p}: its points are not on a regular grid (absolute x/y axes); "
                           f"expected {what} with incremental x and y axes")
    dx, dy = abs(x3p.header.x.increment), abs(x3p.header.y.increment)
    for axis, inc in (("x", dx), ("y", dy)):
        if inc > MAX_INCREMENT_M:
            raise PsbenchError(
                f"{p}: the {axis} increment is {inc:g} m per pixel, evidently the pixel size "
                f"in um written where ISO 25178-72 expects metres ({inc * 1e-6:g} m); "
                f"fix the file's increments")
    if not math.isclose(dx, dy, rel_tol=1e-6):
        raise PsbenchError(f"{p}: x and y increments differ ({dx * 1e6:g} vs {dy * 1e6:g} um); "
                           f"expected square pixels (resample the scan first)")
    z = x3p.layers[0].z
    valid = np.isfinite(z)  # x3pio turns the file's validity mask into NaN
    if valid.any():
        span = float(z[valid].max() - z[valid].min())
        extent = max(z.shape) * dx
        if span > MAX_HEIGHT_ASPECT * extent:
            raise PsbenchError(
                f"{p}: heights span {span:g} m over a {extent:g} m wide scan, evidently "
                f"heights in um written where ISO 25178-72 expects metres")
    height = np.where(valid, z * 1e6, np.nan).astype(np.float32)
    valid &= np.isfinite(height)  # a height beyond float32's range is not usable
    # metres -> um to 12 digits, so 6.25e-06 m reads as 6.25 um (not 6.249999999999999)
    pixel_size = float(f"{dx * 1e6:.12g}")
    return Topography(height=height, valid=valid, pixel_size=pixel_size,
                      meta=_meta(x3p.metadata), name=p.stem)


def fill_invalid(height, valid):
    """Heights with every invalid pixel set to its nearest valid neighbour's height.

    Parameters
    ----------
    height : (H, W) float
    valid : (H, W) bool, at least one True

    Returns
    -------
    (H, W) float64
        Finite everywhere; a rendered scan then has no cliffs at the edge of the measured
        region (no cast shadows or steep normals that the scan never had).
    """
    from scipy import ndimage

    z = np.asarray(height, dtype=np.float64)
    if valid.all():
        return z.copy()
    idx = ndimage.distance_transform_edt(~valid, return_distances=False, return_indices=True)
    return z[idx[0], idx[1]]


def surface_from_topography(topography, *, object_mask=None, scale=1.0, name=None):
    """A :class:`~psbench.surfaces.Surface` from a measured topography.

    Parameters
    ----------
    topography : Topography
        Heights in µm with their valid points and pixel size.
    object_mask : (H, W) bool array_like, optional
        Region of interest; the surface's object mask is it AND ``topography.valid``
        (default: the valid points).
    scale : float, default 1
        Height exaggeration: heights in pixel units are ``height_um / pixel_size * scale``.
    name : str, optional
        Default: the topography's name (or "topography").

    Returns
    -------
    Surface
        Heights in pixel units (µm divided by the pixel size in µm); invalid points take
        their nearest valid neighbour's height and lie outside the object mask.
    """
    if not isinstance(topography, Topography):
        raise PsbenchError(f"topography must be a psbench Topography, got "
                           f"{type(topography).__name__}")
    valid = np.asarray(topography.valid, dtype=bool)
    if not valid.any():
        raise PsbenchError(f"topography {topography.name!r} has no valid points")
    scale = float(scale)
    if not math.isfinite(scale) or scale <= 0:
        raise PsbenchError(f"scale must be a positive finite number, got {scale}")
    object_mask = valid if object_mask is None else valid & as_mask(object_mask, valid.shape,
                                                                    "object_mask")
    z = fill_invalid(topography.height, valid) / float(topography.pixel_size) * scale
    label = name if name is not None else (topography.name or "topography")
    return finish(str(label), z, np.asarray(object_mask, dtype=bool), normals_from_height(z))
