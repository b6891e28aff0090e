"""Image stacks, DiLiGenT-layout folders, psbench capture folders and run outputs.

Images
------
:func:`read_images` reads 8-, 12- or 16-bit PNG/TIFF files with OpenCV
(``cv2.IMREAD_UNCHANGED``: the bit depth is never changed by the decoder) and
converts them **explicitly** to linear float32 in [0, 1] by dividing by the
largest code of the data's bit depth (8-bit -> /255, 16-bit -> /65535). OpenCV
has no 12-bit container: 12-bit sensor data is stored in 16-bit files. psbench
does **not** guess this from pixel values (a dark frame of genuine 16-bit data
can have a small maximum); pass ``bits=12`` explicitly, or record ``"bits": 12``
in a capture folder's ``psbench.json`` (``read_dataset`` then divides by 4095).
Colour images are converted to BT.601 luma ``0.299 R + 0.587 G + 0.114 B``
(alpha dropped). Float32 TIFFs are returned unchanged.

Folders (:func:`read_dataset`)
------------------------------
DiLiGenT layout::

    filenames.txt            one image file name per line (k lines)
    001.png ... 096.png      the images
    light_directions.txt     k x 3 unit vectors towards the lights (x right, y up, z to camera)
    light_intensities.txt    k x 3 (RGB) or k x 1; images are divided by it
    mask.png                 object mask (non-zero = object), optional
    Normal_gt.mat            optional ground truth, key ``Normal_gt`` (H, W, 3)
    normals.npy              optional ground truth as float32 (H, W, 3) (psbench writes this)

psbench capture folders add ``psbench.json`` (metadata: ``lights`` spec, ``ring``
ids, ``exposure``, ``bits``, ``current_mA``, ``calibration`` folder reference, ...)
and ``dark.png``. When the folder holds a calibration (``calibration/calibration.json``
or the folder named by ``psbench.json``'s ``calibration`` key), ``read_dataset``
applies it automatically (:func:`psbench.calibrate.apply_calibration`: dark ->
response -> flat field / near light -> powers) and takes the calibrated light
directions; ``calibration="none"`` reads the raw images.

Light directions are checked: a row whose norm differs from 1 by more than
``unit_tol`` (1e-3) is renormalised with a :class:`PsbenchWarning`; a row whose
norm is off by more than 10 % (or zero) is an error (the file is probably not a
direction list); rows with z < 0 (pointing away from the camera) are an error
naming the file and the 1-based rows.

Light intensities for grayscale images given as k x 3 RGB are reduced to their
BT.601 luma; for colour images each channel is divided by its own intensity
before the luma conversion.

Frame: x right, y up, z towards the camera -- DiLiGenT uses the same one (least
squares over all 96 images reproduces the published 8.41 deg / 8.39 deg on cat /
bear with no axis flip).
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._checks import PsbenchError, as_images, as_mask
from ._fs import atomic_write

__all__ = ["Dataset", "PsbenchWarning", "read_images", "read_image", "write_image",
           "read_dataset", "write_dataset", "write_outputs", "encode_normals",
           "write_ply", "read_lights", "atomic_dir", "LUMA"]

#: BT.601 luma weights (R, G, B)
LUMA = np.array([0.299, 0.587, 0.114])
_IMAGE_EXT = (".png", ".tif", ".tiff")


class PsbenchWarning(UserWarning):
    """Input was accepted after a correction (e.g. renormalised light directions)."""


def _cv2():
    import cv2
    return cv2


# --------------------------------------------------------------------------- images
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


def write_image(path, img, bits=16):
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
    if p.suffix.lower() not in _IMAGE_EXT:
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
@dataclass
class Dataset:
    """A photometric stereo data set read from a folder.

    Attributes
    ----------
    images : (k, H, W) float32
        Linear images divided by the light intensities (and calibrated when a
        calibration was applied).
    lights : Layout
        Light directions (power 1; ring ids when known).
    mask : (H, W) bool
    normals : (H, W, 3) float32 or None
        Ground truth when the folder has it.
    names : list of str
        Image file names.
    meta : dict
        ``psbench.json`` contents plus ``"calibrated"`` (bool) and ``"format"``.
    path : Path
    """

    images: np.ndarray
    lights: object
    mask: np.ndarray
    normals: np.ndarray | None
    names: list
    meta: dict = field(default_factory=dict)
    path: Path | None = None

    @property
    def k(self) -> int:
        return int(self.images.shape[0])

    def subset(self, index) -> "Dataset":
        """The data set restricted to images ``index`` (ints or bool mask)."""
        idx = np.arange(self.k)[index]
        return Dataset(self.images[idx], self.lights.subset(idx), self.mask, self.normals,
                       [self.names[i] for i in idx], dict(self.meta), self.path)


def _read_names(folder):
    f = folder / "filenames.txt"
    if f.is_file():
        names = [ln.strip() for ln in f.read_text().splitlines() if ln.strip()]
        if not names:
            raise PsbenchError(f"{f}: empty file list")
        return names
    names = sorted(p.name for p in folder.iterdir()
                   if p.suffix.lower() in _IMAGE_EXT and p.stem.isdigit())
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
    from .lights import layout

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
        mask = m > 0
    else:
        mask = np.ones((H, W), dtype=bool)

    normals = None
    npy, mat = folder / "normals.npy", folder / "Normal_gt.mat"
    if npy.is_file():
        normals = np.load(npy).astype(np.float32)
        src = npy
    elif mat.is_file():
        import scipy.io as sio
        d = sio.loadmat(mat)
        if "Normal_gt" not in d:
            raise PsbenchError(f"{mat}: no key 'Normal_gt' (keys: {[x for x in d if not x.startswith('__')]})")
        normals = d["Normal_gt"].astype(np.float32)
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
        from . import calibrate as _cal
        calib = _cal.load_calibration(calib_path)
        dark = None
        dp = folder / "dark.png"
        if dp.is_file():
            dark = read_image(dp, bits=bits)
        images = _cal.apply_calibration(images, calib, dark=dark)
        if calib.directions is not None:
            if calib.directions.shape != (k, 3):
                raise PsbenchError(
                    f"calibration {calib_path}: {calib.directions.shape[0]} light directions for {k} images")
            dirs = calib.directions
        positions = calib.positions
        meta["calibrated"] = True
        meta["calibration_path"] = str(calib_path)
        meta["calibration_steps"] = calib.steps()
    lights = layout(dirs, ring=ring, positions=positions)
    return Dataset(images=images, lights=lights, mask=mask, normals=normals, names=names,
                   meta=meta, path=folder)


# --------------------------------------------------------------------------- writing
class atomic_dir:
    """Context manager: build a folder in a temp dir beside ``target`` and rename it
    into place on success; on any error (or KeyboardInterrupt) the temp dir is removed
    and ``target`` is left untouched. Yields the temp dir Path.

    ``overwrite=True`` replaces an existing target (old one moved aside, then removed).
    """

    def __init__(self, target, *, overwrite=False):
        self.target = Path(target)
        self.overwrite = overwrite
        self.tmp = None

    def __enter__(self):
        t = self.target
        if t.exists() and not self.overwrite:
            raise PsbenchError(f"output folder {str(t)!r} already exists (pass overwrite=True to replace it)")
        t.parent.mkdir(parents=True, exist_ok=True)
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{t.name}.partial-", dir=t.parent))
        return self.tmp

    def __exit__(self, exc_type, exc, tb):
        if exc_type is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            return False
        t = self.target
        if t.exists():
            old = Path(tempfile.mkdtemp(prefix=f".{t.name}.old-", dir=t.parent))
            os.replace(t, old / "x")
            os.replace(self.tmp, t)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(self.tmp, t)
        return False


def _fmt_rows(a):
    return "".join(" ".join(repr(float(v)) for v in row) + "\n" for row in np.atleast_2d(a))


def write_dataset(path, images, lights, mask=None, normals=None, *, bits=16, meta=None,
                  names=None, intensities=None, overwrite=False, extra=None):
    """Write a DiLiGenT-layout folder atomically (temp dir beside ``path``, then rename).

    Parameters
    ----------
    path : str or Path
        Target folder (must not exist unless ``overwrite``).
    images : (k, H, W) float in [0, 1] or uint8/uint16
        Written as ``001.png`` ... at ``bits`` (8/12/16; 12 in 16-bit containers,
        recorded as ``"bits": 12`` in psbench.json).
    lights : (k, 3) array_like or Layout
        Written with full float64 precision; ring ids (and near-light positions,
        if the layout has them) go to psbench.json.
    mask : (H, W) bool, optional
        ``mask.png`` (0/255).
    normals : (H, W, 3), optional
        ``normals.npy`` (float32).
    meta : dict, optional
        Written to ``psbench.json`` (with ``bits``, ``ring``, ``k``).
    names : list of str, optional
        File names (default ``001.png`` ...).
    intensities : (k,) or (k, 3), optional
        ``light_intensities.txt`` (default ones, k x 3).
    extra : dict name -> callable(tmpdir), optional
        Extra writers run inside the temp dir before the rename.
    """
    from .lights import Layout, layout as _layout

    raw_int = np.asarray(images)
    if raw_int.ndim != 3:
        raise PsbenchError(f"images must have shape (k, H, W), got {raw_int.shape}")
    imgs = raw_int if np.issubdtype(raw_int.dtype, np.unsignedinteger) else as_images(raw_int)
    k, H, W = imgs.shape
    lay = lights if isinstance(lights, Layout) else _layout(np.asarray(lights, dtype=float))
    if lay.k != k:
        raise PsbenchError(f"lights has {lay.k} directions for {k} images")
    m = None if mask is None else as_mask(mask, (H, W), "mask")
    if normals is not None:
        normals = np.asarray(normals, dtype=np.float32)
        if normals.shape != (H, W, 3):
            raise PsbenchError(f"normals must have shape ({H}, {W}, 3), got {normals.shape}")
    if names is None:
        names = [f"{i + 1:03d}.png" for i in range(k)]
    if len(names) != k:
        raise PsbenchError(f"names has {len(names)} entries for {k} images")
    inten = np.ones((k, 3)) if intensities is None else np.asarray(intensities, dtype=float)
    if inten.shape[0] != k:
        raise PsbenchError(f"intensities has {inten.shape[0]} rows for {k} images")
    md = dict(meta or {})
    md.setdefault("bits", int(bits) if not np.issubdtype(imgs.dtype, np.unsignedinteger)
                  else int(np.iinfo(imgs.dtype).bits))
    md.setdefault("ring", [int(r) for r in lay.ring])
    md.setdefault("k", k)
    if lay.positions is not None:
        md.setdefault("positions", np.asarray(lay.positions).tolist())
    with atomic_dir(path, overwrite=overwrite) as tmp:
        for n, img in zip(names, imgs):
            write_image(tmp / n, img, bits=bits)
        (tmp / "filenames.txt").write_text("".join(n + "\n" for n in names))
        (tmp / "light_directions.txt").write_text(_fmt_rows(lay.directions))
        (tmp / "light_intensities.txt").write_text(_fmt_rows(inten.reshape(k, -1)))
        if m is not None:
            write_image(tmp / "mask.png", (m * 255).astype(np.uint8))
        if normals is not None:
            np.save(tmp / "normals.npy", normals)
        if extra:
            for fn in extra.values():
                fn(tmp)
        (tmp / "psbench.json").write_text(json.dumps(md, indent=1, default=_json_default))
    return Path(path)


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")


# --------------------------------------------------------------------------- outputs
def encode_normals(normals, mask=None):
    """Fig. 5.17 colour code: [r, g, b] = [(nx+1)/2, (ny+1)/2, nz], (H, W, 3) float in [0, 1].

    nz < 0 (invalid for a visible surface) is clipped to 0; pixels outside ``mask``
    are black.
    """
    n = np.asarray(normals, dtype=np.float64)
    rgb = np.stack([(n[..., 0] + 1) / 2, (n[..., 1] + 1) / 2, n[..., 2]], axis=-1)
    rgb = np.clip(rgb, 0.0, 1.0)
    if mask is not None:
        rgb[~np.asarray(mask, bool)] = 0.0
    return rgb


def write_ply(path, height, mask=None, *, binary=True):
    """Write a height map as a triangle mesh (PLY).

    Vertices are the masked pixels at ``(x, y, z) = (c - (W-1)/2, (H-1)/2 - r, height)``
    (pixel units, psbench's frame); every 2x2 pixel block whose four corners are in
    the mask gives two triangles (counter-clockwise seen from +z). Vectorized.
    """
    h = np.asarray(height, dtype=np.float64)
    if h.ndim != 2:
        raise PsbenchError(f"height must have shape (H, W), got {h.shape}")
    H, W = h.shape
    m = as_mask(mask, (H, W), "mask") & np.isfinite(h)
    idx = -np.ones((H, W), dtype=np.int64)
    idx[m] = np.arange(int(m.sum()))
    r, c = np.nonzero(m)
    verts = np.stack([c - (W - 1) / 2.0, (H - 1) / 2.0 - r, h[m]], axis=1).astype(np.float32)
    a, b = idx[:-1, :-1], idx[:-1, 1:]   # top-left, top-right
    cc, d = idx[1:, :-1], idx[1:, 1:]    # bottom-left, bottom-right
    quad = (a >= 0) & (b >= 0) & (cc >= 0) & (d >= 0)
    # y is up, so the bottom row is lower: CCW from +z is (bl, br, tr) and (bl, tr, tl)
    t1 = np.stack([cc[quad], d[quad], b[quad]], axis=1)
    t2 = np.stack([cc[quad], b[quad], a[quad]], axis=1)
    faces = np.concatenate([t1, t2]).astype(np.int32)
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fmt = "binary_little_endian" if binary else "ascii"
    header = (f"ply\nformat {fmt} 1.0\ncomment psbench height map mesh (pixel units)\n"
              f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    def write(f):
        f.write(header.encode("ascii"))
        if binary:
            f.write(verts.astype("<f4").tobytes())
            rec = np.zeros(len(faces), dtype=[("n", "u1"), ("v", "<i4", 3)])
            rec["n"] = 3
            rec["v"] = faces
            f.write(rec.tobytes())
        else:
            np.savetxt(f, verts, fmt="%.6g")
            np.savetxt(f, np.hstack([np.full((len(faces), 1), 3), faces]), fmt="%d")

    atomic_write(p, write, fsync=False)
    return len(verts), len(faces)


def write_outputs(path, result, *, mask=None, ply=True, binary_ply=True):
    """Write a solve result to a folder.

    Files: ``normals.npy`` (H, W, 3) float32, ``normals.png`` (16-bit RGB, Fig. 5.17
    code), ``albedo.npy``, ``albedo.png`` (16-bit, divided by the max albedo over the
    mask), ``height.npy`` and ``mesh.ply`` (when the result has a height or
    :func:`psbench.integrate` is available), ``valid.npy`` + ``valid/NNN.png``
    (0/255, True = used), ``weights.npy`` + ``weights/NNN.png`` (16-bit, divided by
    the max weight), likewise ``ring_weights`` (WPS). Each file is written to a temp name and renamed.

    Parameters
    ----------
    path : str or Path
    result : psbench Result (or any object with ``.normals`` and optional
        ``.albedo .height .valid .weights .ring_weights``)
    mask : (H, W) bool, optional
    """
    out = Path(path)
    out.mkdir(parents=True, exist_ok=True)
    n = np.asarray(result.normals, dtype=np.float32)
    H, W = n.shape[:2]
    m = as_mask(mask, (H, W), "mask")
    written = []

    def save_npy(name, arr):
        atomic_write(out / name, lambda fh: np.save(fh, arr), fsync=False)
        written.append(name)

    def save_png(name, img, bits=16):
        dst = out / name
        tmp = dst.with_name(".tmp-" + dst.name)
        write_image(tmp, img, bits=bits)
        os.replace(tmp, dst)
        written.append(name)

    save_npy("normals.npy", n)
    save_png("normals.png", encode_normals(n, m))
    alb = getattr(result, "albedo", None)
    if alb is not None:
        alb = np.asarray(alb, dtype=np.float32)
        save_npy("albedo.npy", alb)
        mx = float(alb[m].max()) if m.any() else 0.0
        save_png("albedo.png", np.where(m, alb / mx, 0) if mx > 0 else np.zeros_like(alb))
    hgt = getattr(result, "height", None)
    if hgt is None:
        try:
            from .integrate import integrate
            hgt = integrate(n, m)
        except Exception as e:  # integrate not available or failed: skip the mesh
            warnings.warn(f"no height written: {e}", PsbenchWarning, stacklevel=2)
    if hgt is not None:
        hgt = np.asarray(hgt, dtype=np.float32)
        save_npy("height.npy", hgt)
        if ply:
            write_ply(out / "mesh.ply", hgt, m, binary=binary_ply)
            written.append("mesh.ply")
    for name, scale in (("valid", None), ("weights", "max"), ("ring_weights", "max")):
        a = getattr(result, name, None)
        if a is None:
            continue
        a = np.asarray(a)
        if a.ndim != 3:
            continue
        save_npy(f"{name}.npy", a)
        (out / name).mkdir(exist_ok=True)
        if name == "valid":
            for i, v in enumerate(a):
                save_png(f"{name}/{i + 1:03d}.png", (v.astype(np.uint8) * 255), bits=8)
        else:
            mx = float(a.max()) or 1.0
            for i, v in enumerate(a):
                save_png(f"{name}/{i + 1:03d}.png", v / mx)
    return written
