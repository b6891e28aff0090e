"""DiLiGenT-layout and psbench capture folders: :func:`read_dataset`, :class:`Dataset`."""
from __future__ import annotations

import json
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError
from .._shared.deprecation import warn_renamed
from ._calibration import apply_calibration, load_calibration
from ._common import IMAGE_EXT, LUMA, PsbenchWarning, cv2 as _cv2
from ._images import read_image, read_images

__all__ = ["Dataset", "read_dataset", "read_lights"]


# --------------------------------------------------------------------------- lights
def read_lights(path, k=None, *, unit_tol=1e-3):
    """Read and check a ``light_directions.txt`` (k x 3).

    Rows with norm within ``unit_tol`` of 1 are kept; rows off by more are
    renormalised with a :class:`PsbenchWarning`; rows off by more than 10 % or
    with z < 0 are errors naming the file and the 1-based rows.
    """
    p = Path(path)
    d = _loadtxt(p, 3)
    if k is not None and d.shape[0] != k:
        raise PsbenchError(f"{p}: {d.shape[0]} light directions for {k} images")
    n = np.linalg.norm(d, axis=1)
    bad = np.flatnonzero(np.abs(n - 1.0) > 0.1)
    if bad.size:
        raise PsbenchError(
            f"{p}: rows {(bad + 1).tolist()} are not unit vectors (norms "
            f"{np.round(n[bad], 4).tolist()}); expected unit directions x y z")
    off = np.flatnonzero(np.abs(n - 1.0) > unit_tol)
    if off.size:
        warnings.warn(f"{p}: rows {(off + 1).tolist()} are not unit vectors "
                      f"(largest |norm-1| = {np.abs(n[off] - 1).max():.3g}); renormalised",
                      PsbenchWarning, stacklevel=2)
    d = d / n[:, None]
    neg = np.flatnonzero(d[:, 2] < 0)
    if neg.size:
        raise PsbenchError(
            f"{p}: rows {(neg + 1).tolist()} point away from the camera (z < 0); "
            "psbench's frame has z towards the camera (x right, y up)")
    return d


def _loadtxt(p, ncols=None):
    if not p.is_file():
        raise PsbenchError(f"file {str(p)!r} does not exist")
    try:
        a = np.loadtxt(p, dtype=np.float64, ndmin=2)
    except ValueError as e:
        raise PsbenchError(f"{p}: not a numeric table ({e})") from None
    if ncols is not None and a.shape[1] != ncols:
        raise PsbenchError(f"{p}: expected {ncols} columns, got {a.shape[1]}")
    if not np.isfinite(a).all():
        raise PsbenchError(f"{p}: holds NaN/inf values")
    return a


# --------------------------------------------------------------------------- dataset
@dataclass(init=False)
class Dataset:
    """A photometric stereo data set read from a folder.

    Attributes
    ----------
    images : (k, H, W) float32
        Linear images divided by the light intensities (and calibrated when a
        calibration was applied).
    lights : Layout
        Light directions (power 1; ring ids when known).
    object_mask : (H, W) bool
        The object region (``mask.png``; all True without one). ``mask`` is its
        deprecated name (argument and attribute).
    normals : (H, W, 3) float32 or None
        Ground truth when the folder has it.
    names : list of str
        Image file names.
    meta : dict
        ``psbench.json`` contents plus ``"calibrated"`` (bool) and ``"format"``;
        ``"pixel_size_um"`` (µm per pixel) when ``psbench.json`` gives it or the applied
        calibration measured it.
    path : Path
    """

    images: np.ndarray
    lights: object
    object_mask: np.ndarray
    normals: np.ndarray | None
    names: list
    meta: dict = field(default_factory=dict)
    path: Path | None = None

    def __init__(self, images, lights, object_mask=None, normals=None, names=None, meta=None,
                 path=None, *, mask=None):
        if mask is not None:
            if object_mask is not None:
                raise TypeError("Dataset() got both mask= (deprecated) and object_mask=")
            warn_renamed("Dataset(mask=...)", "object_mask=...")
            object_mask = mask
        if object_mask is None or names is None:
            raise TypeError("Dataset() needs images, lights, object_mask, normals and names")
        self.images, self.lights, self.object_mask = images, lights, object_mask
        self.normals, self.names = normals, names
        self.meta = {} if meta is None else meta
        self.path = path

    @property
    def mask(self):
        """Deprecated name of :attr:`object_mask`."""
        warn_renamed("Dataset.mask", "Dataset.object_mask")
        return self.object_mask

    @mask.setter
    def mask(self, value):
        warn_renamed("Dataset.mask", "Dataset.object_mask")
        self.object_mask = value

    @property
    def k(self) -> int:
        """Number of images."""
        return int(self.images.shape[0])

    def subset(self, index) -> "Dataset":
        """The data set restricted to images ``index`` (ints or bool mask)."""
        idx = np.arange(self.k)[index]
        return Dataset(self.images[idx], self.lights.subset(idx), self.object_mask, self.normals,
                       [self.names[i] for i in idx], dict(self.meta), self.path)


def _read_names(folder):
    f = folder / "filenames.txt"
    if f.is_file():
        names = [ln.strip() for ln in f.read_text().splitlines() if ln.strip()]
        if not names:
            raise PsbenchError(f"{f}: empty file list")
        return names
    names = sorted(p.name for p in folder.iterdir()
                   if p.suffix.lower() in IMAGE_EXT and p.stem.isdigit())
    if not names:
        raise PsbenchError(
            f"folder {str(folder)!r} has neither filenames.txt nor numbered images (001.png ...)")
    return names


def _find_calibration(folder, meta, calibration):
    if calibration is None or calibration is False or calibration == "none":
        return None
    if calibration == "auto":
        ref = meta.get("calibration")
        cands = [folder / ref] if ref else []
        cands.append(folder / "calibration")
        for c in cands:
            c = Path(c)
            if (c / "calibration.json").is_file() or (c.is_file() and c.suffix == ".json"):
                return c
        return None
    c = Path(calibration)
    if not c.exists():
        raise PsbenchError(f"calibration={str(c)!r} does not exist")
    return c


def read_dataset(path, *, calibration="auto", bits=None, unit_tol=1e-3):
    """Read a DiLiGenT-layout or psbench capture folder.

    Parameters
    ----------
    path : str or Path
        The folder.
    calibration : "auto", "none", None or path
        "auto": apply the folder's saved calibration if it has one
        (``calibration/`` or ``psbench.json["calibration"]``); "none"/None: raw
        images; a path: that calibration folder or JSON file.
    bits : int, optional
        Significant bits of 16-bit images; default ``psbench.json["bits"]`` when
        present, else the container depth.
    unit_tol : float
        Tolerance on the norm of light directions (see module docstring).

    Returns
    -------
    Dataset
    """
    from ..lights import layout

    folder = Path(path)
    if not folder.is_dir():
        raise PsbenchError(f"data folder {str(folder)!r} does not exist or is not a folder")
    meta = {}
    mj = folder / "psbench.json"
    if mj.is_file():
        try:
            meta = json.loads(mj.read_text())
        except json.JSONDecodeError as e:
            raise PsbenchError(f"{mj}: invalid JSON ({e})") from None
    names = _read_names(folder)
    k = len(names)
    ld = folder / "light_directions.txt"
    if not ld.is_file():
        raise PsbenchError(f"{ld} does not exist: a data folder needs light_directions.txt (k x 3)")
    nrows = _loadtxt(ld).shape[0]
    if nrows != k:
        src = "filenames.txt" if (folder / "filenames.txt").is_file() else "numbered images"
        raise PsbenchError(f"{ld}: {nrows} light directions but {k} images ({src})")
    dirs = read_lights(ld, k, unit_tol=unit_tol)

    li = folder / "light_intensities.txt"
    rgb_scale = None
    inten = np.ones(k)
    if li.is_file():
        a = _loadtxt(li)
        if a.shape[0] != k:
            raise PsbenchError(f"{li}: {a.shape[0]} rows but {k} images")
        if a.shape[1] not in (1, 3):
            raise PsbenchError(f"{li}: expected 1 or 3 columns (k x 1 or k x 3 RGB), got {a.shape[1]}")
        if (a <= 0).any():
            rows = np.flatnonzero((a <= 0).any(axis=1)) + 1
            raise PsbenchError(f"{li}: rows {rows.tolist()} hold non-positive intensities")
        if a.shape[1] == 3:
            rgb_scale = a
            inten = a @ LUMA
        else:
            inten = a[:, 0]
    bits = meta.get("bits") if bits is None else bits
    if bits is not None and int(bits) == 8:
        bits = None
    images = read_images([folder / n for n in names], bits=bits, rgb_scale=rgb_scale)
    colour = _cv2().imread(str(folder / names[0]), _cv2().IMREAD_UNCHANGED).ndim == 3
    if rgb_scale is None or not colour:
        images /= inten.astype(np.float32)[:, None, None]
    H, W = images.shape[1:]

    mp = folder / "mask.png"
    if mp.is_file():
        m = read_image(mp, raw=True)
        if m.ndim == 3:
            m = m[..., :3].max(axis=2)
        if m.shape != (H, W):
            raise PsbenchError(f"{mp}: mask is {m.shape[1]}x{m.shape[0]} (WxH) but the images are {W}x{H}")
        object_mask = m > 0
    else:
        object_mask = np.ones((H, W), dtype=bool)

    normals = None
    npy, mat = folder / "normals.npy", folder / "Normal_gt.mat"
    if npy.is_file():
        try:
            normals = np.load(npy, allow_pickle=False).astype(np.float32)
        except Exception as e:  # noqa: BLE001 - any damage: name the file, say what was expected
            raise PsbenchError(f"{npy}: unreadable ({type(e).__name__}: {e}); expected a .npy "
                               f"array of float normals ({H}, {W}, 3)") from None
        src = npy
    elif mat.is_file():
        import scipy.io as sio
        try:
            d = sio.loadmat(mat)
        except Exception as e:  # noqa: BLE001 - a corrupt .mat raises many kinds of errors
            raise PsbenchError(f"{mat}: unreadable ({type(e).__name__}: {e}); expected a MATLAB "
                               f"file with key 'Normal_gt' ({H}, {W}, 3)") from None
        if "Normal_gt" not in d:
            raise PsbenchError(f"{mat}: no key 'Normal_gt' (keys: {[x for x in d if not x.startswith('__')]})")
        try:
            normals = np.asarray(d["Normal_gt"]).astype(np.float32)
        except (TypeError, ValueError) as e:
            raise PsbenchError(f"{mat}: 'Normal_gt' is not numeric ({e}); expected ({H}, {W}, 3) "
                               "floats") from None
        src = mat
    if normals is not None and normals.shape != (H, W, 3):
        raise PsbenchError(f"{src}: normals have shape {normals.shape}, images are ({H}, {W}) -> expected ({H}, {W}, 3)")

    ring = meta.get("ring")
    if ring is not None and len(ring) != k:
        raise PsbenchError(f"{mj}: 'ring' has {len(ring)} ids for {k} images")

    meta = dict(meta)
    meta["format"] = "psbench" if mj.is_file() else "diligent"
    meta["calibrated"] = False
    calib_path = _find_calibration(folder, meta, calibration)
    positions = meta.get("positions")
    if positions is not None:
        positions = np.asarray(positions, dtype=np.float64)
        if positions.shape != (k, 3):
            raise PsbenchError(f"{mj}: 'positions' must be {k} x 3, got {positions.shape}")
    if calib_path is not None:
        calib = load_calibration(calib_path)
        dark = None
        dp = folder / "dark.png"
        if dp.is_file():
            dark = read_image(dp, bits=bits)
        images = apply_calibration(images, calib, dark=dark)
        if calib.directions is not None:
            if calib.directions.shape != (k, 3):
                raise PsbenchError(
                    f"calibration {calib_path}: {calib.directions.shape[0]} light directions for {k} images")
            dirs = calib.directions
        positions = calib.positions
        meta["calibrated"] = True
        meta["calibration_path"] = str(calib_path)
        meta["calibration_steps"] = calib.steps()
        if calib.pixel_size is not None:  # measured in mm per pixel
            meta["pixel_size_um"] = float(calib.pixel_size) * 1000.0
    lights = layout(dirs, ring=ring, positions=positions)
    return Dataset(images=images, lights=lights, object_mask=object_mask, normals=normals,
                   names=names,
                   meta=meta, path=folder)
