"""Folders of real scans: ``guns.csv`` and the X3P files it names, and one pixel size per pair.

A study folder holds X3P topographies (ISO 25178-72) and a ``guns.csv`` with the columns
``scan,gun``: ``scan`` is a file's stem (``TW01-01`` for ``TW01-01.x3p``; a name with the
``.x3p`` suffix is accepted too), ``gun`` the firearm that fired it (same gun = same
source). :func:`read_guns` checks the two agree both ways before any work. The folder is
``$PSBENCH_X3P``, default ``../shared/data/forensic/weller`` (relative to the working
directory, as ``$PSBENCH_DATA`` is for the DiLiGenT folders).

Two scans compared with each other must share a pixel size; :func:`match_pixel_size`
(arrays) and :func:`match_topographies` (:class:`~psbench.surfaces.Topography`) resample
the finer one to the coarser one's pixel size and say so in a :class:`PsbenchWarning`.
"""
from __future__ import annotations

import math
import os
import warnings
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError, as_mask
from ..io import PsbenchWarning, read_x3p
from ..surfaces import Topography

__all__ = ["X3P_ENV", "DEFAULT_X3P", "scans_folder", "read_guns", "resample",
           "match_pixel_size", "match_topographies"]

#: environment variable naming the folder of X3P scans with their guns.csv
X3P_ENV = "PSBENCH_X3P"
#: the folder used when $PSBENCH_X3P is not set
DEFAULT_X3P = "../shared/data/forensic/weller"
#: relative difference below which two pixel sizes are the same
PIXEL_RTOL = 1e-6


def scans_folder(folder=None):
    """The scan folder: ``folder``, else ``$PSBENCH_X3P``, else :data:`DEFAULT_X3P` (a Path)."""
    if folder is None:
        folder = os.environ.get(X3P_ENV) or DEFAULT_X3P
    return Path(folder)


def _shorten(names, n=5):
    names = sorted(names)
    more = f" and {len(names) - n} more" if len(names) > n else ""
    return ", ".join(names[:n]) + more


def read_guns(folder=None):
    """The scans of a folder and the gun that fired each, from its ``guns.csv``.

    Parameters
    ----------
    folder : str or Path, optional
        A folder of ``.x3p`` files and ``guns.csv`` (default :func:`scans_folder`).

    Returns
    -------
    pandas.DataFrame
        One row per scan in the order of ``guns.csv``: ``scan`` (str, the file's stem),
        ``gun`` (str, as written), ``path`` (Path of the ``.x3p`` file).

    Raises
    ------
    PsbenchError
        One line naming the file: no folder, no ``guns.csv``, columns other than
        ``scan,gun``, an empty or repeated scan or an empty gun, scans that ``guns.csv``
        names but the folder lacks, or ``.x3p`` files that ``guns.csv`` does not name.
    """
    import pandas as pd

    root = scans_folder(folder)
    if not root.is_dir():
        raise PsbenchError(f"scan folder {str(root)!r} does not exist; expected a folder of "
                           f".x3p files with guns.csv (set {X3P_ENV} or pass folder=)")
    csv = root / "guns.csv"
    if not csv.is_file():
        raise PsbenchError(f"{csv}: missing; expected a guns.csv with the columns scan,gun "
                           f"naming every .x3p file of {root}")
    try:
        table = pd.read_csv(csv, dtype=str, keep_default_na=False, skipinitialspace=True)
    except Exception as exc:  # noqa: BLE001 - any parser failure is a bad file
        raise PsbenchError(f"{csv}: not a readable CSV ({exc}); expected columns scan,gun") from None
    table.columns = [str(c).strip().lower() for c in table.columns]
    if not {"scan", "gun"} <= set(table.columns):
        raise PsbenchError(f"{csv}: columns {', '.join(table.columns) or 'none'}; expected "
                           f"the columns scan,gun")
    table = table[["scan", "gun"]].apply(lambda col: col.str.strip())
    table["scan"] = [s[:-4] if s.lower().endswith(".x3p") else s for s in table["scan"]]
    if table.empty:
        raise PsbenchError(f"{csv}: names no scans; expected one row scan,gun per .x3p file")
    empty = table.index[(table["scan"] == "") | (table["gun"] == "")]
    if len(empty):
        raise PsbenchError(f"{csv}: row {int(empty[0]) + 2} has an empty scan or gun; expected "
                           f"a scan name and a gun on every row")
    dup = table["scan"][table["scan"].duplicated()]
    if len(dup):
        raise PsbenchError(f"{csv}: scan {dup.iloc[0]!r} is listed more than once; expected "
                           f"each scan once")
    files = {p.stem: p for p in root.iterdir() if p.suffix.lower() == ".x3p" and p.is_file()}
    missing = set(table["scan"]) - set(files)
    if missing:
        raise PsbenchError(f"{csv}: names {len(missing)} scan(s) with no .x3p file in {root}: "
                           f"{_shorten(missing)}; expected a <scan>.x3p for every row")
    unnamed = set(files) - set(table["scan"])
    if unnamed:
        raise PsbenchError(f"{csv}: does not name {len(unnamed)} .x3p file(s) of {root}: "
                           f"{_shorten(f + '.x3p' for f in unnamed)}; expected a row scan,gun "
                           f"for every scan")
    table["path"] = [files[s] for s in table["scan"]]
    return table.reset_index(drop=True)


def resample(height, valid=None, *, pixel_size, to):
    """Resample a height map to another pixel size, valid points only.

    Parameters
    ----------
    height : (H, W) array_like of float
        Heights (any unit); NaN where not measured.
    valid : (H, W) bool array_like, optional
        Measured points (default: the finite heights).
    pixel_size : float
        Its pixel size (µm).
    to : float
        The pixel size wanted (µm).

    Returns
    -------
    height : (H', W') float32
        ``H' = round(H * pixel_size / to)``; each output pixel averages the valid input
        pixels it covers (area averaging when coarsening, bilinear when refining, both as
        normalised convolutions so invalid points never leak in); NaN where not valid.
    valid : (H', W') bool
        True where at least half of the output pixel's support was valid.
    """
    import cv2

    z = np.asarray(height, dtype=np.float64)
    if z.ndim != 2:
        raise PsbenchError(f"height must have shape (H, W), got shape {z.shape}")
    ok = np.isfinite(z) if valid is None else as_mask(valid, z.shape, "valid") & np.isfinite(z)
    for name, value in (("pixel_size", pixel_size), ("to", to)):
        if not (isinstance(value, (int, float, np.number)) and math.isfinite(value) and value > 0):
            raise PsbenchError(f"{name} must be a positive number of um, got {value!r}")
    factor = float(pixel_size) / float(to)
    shape = (max(1, round(z.shape[1] * factor)), max(1, round(z.shape[0] * factor)))  # (W, H)
    interp = cv2.INTER_AREA if factor < 1 else cv2.INTER_LINEAR
    w = ok.astype(np.float64)
    num = cv2.resize(np.where(ok, z, 0.0), shape, interpolation=interp)
    den = cv2.resize(w, shape, interpolation=interp)
    keep = den >= 0.5
    out = np.full(den.shape, np.nan, dtype=np.float32)
    out[keep] = (num[keep] / den[keep]).astype(np.float32)
    return out, keep


def match_pixel_size(height_a, height_b, valid_a=None, valid_b=None, *, pixel_size_a,
                     pixel_size_b, names=("A", "B")):
    """Two scans at one pixel size: the finer one resampled to the coarser one's.

    Parameters
    ----------
    height_a, height_b : (H, W) array_like of float
        Heights, NaN where not measured (shapes may differ).
    valid_a, valid_b : (H, W) bool array_like, optional
        Measured points (default: the finite heights).
    pixel_size_a, pixel_size_b : float
        Their pixel sizes (µm).
    names : (str, str)
        How the warning names the two scans (e.g. their file names).

    Returns
    -------
    height_a, height_b, valid_a, valid_b, pixel_size
        Unchanged (as float32 and bool) when the pixel sizes agree to :data:`PIXEL_RTOL`;
        otherwise the finer scan resampled (:func:`resample`) and a
        :class:`~psbench.io.PsbenchWarning` saying which scan was resampled from what to what.
    """
    out = []
    for h, v in ((height_a, valid_a), (height_b, valid_b)):
        z = np.asarray(h, dtype=np.float32)
        out.append((z, np.isfinite(z) if v is None else as_mask(v, z.shape, "valid")
                    & np.isfinite(z)))
    (za, va), (zb, vb) = out
    pa, pb = float(pixel_size_a), float(pixel_size_b)
    for name, value in (("pixel_size_a", pa), ("pixel_size_b", pb)):
        if not math.isfinite(value) or value <= 0:
            raise PsbenchError(f"{name} must be a positive number of um, got {value!r}")
    if math.isclose(pa, pb, rel_tol=PIXEL_RTOL):
        return za, zb, va, vb, pa
    coarse = max(pa, pb)
    fine_name, fine_px = (names[0], pa) if pa < pb else (names[1], pb)
    other = names[1] if pa < pb else names[0]
    warnings.warn(f"{fine_name} ({fine_px:g} um per pixel) resampled to {coarse:g} um per "
                  f"pixel to be compared with {other}", PsbenchWarning, stacklevel=2)
    if pa < pb:
        za, va = resample(za, va, pixel_size=pa, to=coarse)
    else:
        zb, vb = resample(zb, vb, pixel_size=pb, to=coarse)
    return za, zb, va, vb, coarse


def match_topographies(a, b):
    """Two :class:`~psbench.surfaces.Topography` (or ``.x3p`` paths) at one pixel size.

    Parameters
    ----------
    a, b : Topography or str or Path

    Returns
    -------
    (Topography, Topography)
        As :func:`match_pixel_size`, the warning naming the files.
    """
    topo = [t if isinstance(t, Topography) else read_x3p(t) for t in (a, b)]
    names = tuple(f"{t.name}.x3p" if t.name else label for t, label in zip(topo, "AB"))
    za, zb, va, vb, px = match_pixel_size(topo[0].height, topo[1].height, topo[0].valid,
                                          topo[1].valid, pixel_size_a=topo[0].pixel_size,
                                          pixel_size_b=topo[1].pixel_size, names=names)
    return tuple(Topography(height=z, valid=v, pixel_size=px, meta=t.meta, name=t.name)
                 for z, v, t in ((za, va, topo[0]), (zb, vb, topo[1])))
