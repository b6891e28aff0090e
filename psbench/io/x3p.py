"""X3P (ISO 25178-72) topographies in and out, through the maintained ``x3pio`` package.

:func:`read_x3p` returns a :class:`~psbench.surfaces.Topography` (heights in µm, NaN and
the file's validity mask as ``valid``, the pixel size in µm, the metadata);
:func:`write_x3p` writes one: heights in metres as float64, x and y increments in metres,
NaN where not valid, MD5 checksums of ``main.xml`` and of the binary data (x3pio writes
them). ``write_x3p(path, t.height, pixel_size=t.pixel_size, valid=t.valid, **t.meta)``
reproduces a topography read by :func:`read_x3p` exactly.
"""
from __future__ import annotations

import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError, as_mask
from .._shared.files import atomic_write
from ..surfaces._topography import Topography, read_topography

__all__ = ["Topography", "read_x3p", "write_x3p", "META_KEYS"]

#: the metadata keys :func:`write_x3p` takes (those :func:`read_x3p` returns in ``meta``)
META_KEYS = ("date", "calibration_date", "creator", "comment", "instrument", "probing_type",
             "probing_identification")
_INSTRUMENT_KEYS = ("manufacturer", "model", "serial", "version")


def read_x3p(path):
    """Read an X3P surface file.

    Parameters
    ----------
    path : str or Path
        An ISO 25178-72 ``.x3p`` file holding one surface layer on a regular grid.

    Returns
    -------
    Topography
        ``.height (H, W) float32`` in µm (NaN where not valid), ``.valid (H, W) bool``
        (measured points: not NaN in the file and not cleared by its validity mask),
        ``.pixel_size`` in µm, ``.meta`` (``date``, ``creator``, ``comment``,
        ``instrument``, ... see :class:`~psbench.surfaces.Topography`), ``.name`` (the
        file's stem).

    Raises
    ------
    PsbenchError
        One line naming the file and what was expected: not a ZIP/X3P file, a wrong MD5
        checksum, a missing ``bindata`` file, a profile or a point cloud, several layers,
        an irregular grid, unequal increments, increments (or heights) evidently in µm
        instead of metres.
    """
    return read_topography(path)


def _datetime(value, key):
    if value is None or isinstance(value, datetime):
        return value
    try:
        return datetime.fromisoformat(str(value))
    except ValueError:
        raise PsbenchError(f"{key} must be a datetime or an ISO 8601 string, got "
                           f"{value!r}") from None


def _metadata(meta):
    """psbench's metadata keywords -> x3pio ``Metadata`` (psbench as the default software)."""
    import x3pio

    from .. import __version__

    bad = sorted(set(meta) - set(META_KEYS))
    if bad:
        raise PsbenchError(f"write_x3p got unknown metadata {bad[0]!r}; valid keys: "
                           f"{', '.join(META_KEYS)}")
    md = x3pio.Metadata.for_software("psbench", __version__)
    if meta.get("date") is not None:
        md.date = _datetime(meta["date"], "date")
    md.calibration_date = _datetime(meta.get("calibration_date"), "calibration_date")
    for key in ("creator", "comment"):
        if meta.get(key) is not None:
            setattr(md, key, str(meta[key]))
    inst = meta.get("instrument")
    if inst is not None:
        if not isinstance(inst, dict) or set(inst) - set(_INSTRUMENT_KEYS):
            raise PsbenchError(f"instrument must be a dict with keys among "
                               f"{', '.join(_INSTRUMENT_KEYS)}, got {inst!r}")
        md.instrument = x3pio.Instrument(**{k: str(inst.get(k, "") or "")
                                            for k in _INSTRUMENT_KEYS})
    if "probing_type" in meta:
        kind = meta["probing_type"]
        valid = [t.value for t in x3pio.ProbingType]
        if kind not in valid:
            raise PsbenchError(f"probing_type={kind!r} is not known; valid choices: "
                               f"{', '.join(valid)}")
        md.probing_system.type = x3pio.ProbingType(kind)
    if meta.get("probing_identification") is not None:
        md.probing_system.identification = str(meta["probing_identification"])
    return md


def write_x3p(path, height, *, pixel_size, valid=None, **meta):
    """Write a height map as an X3P (ISO 25178-72) surface file, atomically.

    Parameters
    ----------
    path : str or Path
        Target file, ending in ``.x3p``; its folder is created if needed.
    height : (H, W) array_like of float
        Heights in µm (H, W >= 2). NaN points are written as not measured.
    pixel_size : float
        Lateral sampling interval in µm (> 0); written as the x and y increments in metres.
    valid : (H, W) bool array_like, optional
        Measured points; the others are written as NaN. Default: the finite heights.
    **meta
        The file's metadata, the keys of :attr:`Topography.meta <psbench.surfaces.Topography>`:
        ``date`` and ``calibration_date`` (datetime or ISO 8601 string; date defaults to
        now, UTC), ``creator``, ``comment``, ``instrument`` (dict of ``manufacturer``,
        ``model``, ``serial``, ``version``; default psbench as the software),
        ``probing_type`` (``"Contacting"``, ``"NonContacting"`` or ``"Software"``, the
        default) and ``probing_identification``.

    Returns
    -------
    Path
        The file written.
    """
    import x3pio

    p = Path(path)
    if p.suffix.lower() != ".x3p":
        raise PsbenchError(f"path must end in .x3p, got {str(path)!r}")
    arr = np.asarray(height)
    if arr.dtype == bool or not (np.issubdtype(arr.dtype, np.integer)
                                 or np.issubdtype(arr.dtype, np.floating)):
        raise PsbenchError(f"height must be a float array of heights in um, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[0] < 2 or arr.shape[1] < 2:
        raise PsbenchError(f"height must have shape (H, W) with H, W >= 2, got shape {arr.shape}")
    try:
        px = float(pixel_size)
    except (TypeError, ValueError):
        raise PsbenchError(f"pixel_size must be a positive number of um, got {pixel_size!r}") from None
    if not math.isfinite(px) or px <= 0:
        raise PsbenchError(f"pixel_size must be a positive number of um, got {pixel_size!r}")
    z = arr.astype(np.float64)  # float32 um -> float64 m is exact back to float32 um
    ok = np.isfinite(z)
    if np.isinf(z).any():
        raise PsbenchError(f"height holds {int(np.isinf(z).sum())} infinite values; use NaN "
                           f"(or valid=) for points that are not measured")
    if valid is not None:
        ok &= as_mask(valid, z.shape, "valid")
    z = np.where(ok, z * 1e-6, np.nan)
    md = _metadata(meta)
    if md.date is None:
        md.date = datetime.now(UTC)
    try:
        data = x3pio.Surface.from_array(z, x_scale=px * 1e-6, y_scale=px * 1e-6,
                                        metadata=md).dumps()
    except x3pio.X3pFormatError as exc:
        raise PsbenchError(f"write_x3p({str(path)!r}): {exc}") from None
    return atomic_write(p, data)
