"""A calibration as data: the :class:`Calibration` record, how it is applied to raw
images (:func:`apply_calibration`), and its folder (``calibration.json`` plus ``.npy``
arrays, written atomically).

:mod:`psbench.calibrate` measures a calibration (the fitting maths and the folder steps)
and re-exports these names; :mod:`psbench.io` needs them to read a calibrated folder,
so they live here, below :mod:`psbench.calibrate`. The corrections applied per image
(hot pixels, response, near-light fields) are here for the same reason.

The folder holds ``calibration.json`` (steps, parameters, response coefficients, pixel
size, provenance) and ``directions.npy``, ``positions.npy``, ``powers.npy``,
``flat.npy``, ``hot.npy`` as present.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError, as_images
from .._shared.deprecation import renamed_args
from ._common import json_default
from ._write import atomic_dir

__all__ = ["Calibration", "apply_calibration", "save_calibration", "load_calibration",
           "hot_pixels", "remove_hot_pixels", "apply_response", "near_light_fields"]

_ARRAYS = ("directions", "positions", "powers", "flat", "hot")


@dataclass
class Calibration:
    """Calibration results; any field may be None (step not done).

    Attributes
    ----------
    directions : (k, 3) or None
    positions : (k, 3) or None
        Light positions (pixel units); enable the near-light correction.
    powers : (k,) or None
    flat : (H, W) float32 or None
    flat_degree : int
    response : (d+1,) or None
        Inverse response polynomial (np.polyval order).
    hot : (H, W) bool or None
    hot_threshold : float or None
    pixel_size : float or None
        Millimetres per pixel.
    near_light : bool
        Apply the near-light correction when positions are known.
    meta : dict
    """

    directions: np.ndarray | None = None
    positions: np.ndarray | None = None
    powers: np.ndarray | None = None
    flat: np.ndarray | None = None
    flat_degree: int = 4
    response: np.ndarray | None = None
    hot: np.ndarray | None = None
    hot_threshold: float | None = None
    pixel_size: float | None = None
    near_light: bool = True
    meta: dict = field(default_factory=dict)

    def steps(self):
        s = []
        if self.hot is not None or self.hot_threshold is not None:
            s.append("dark")
        if self.response is not None:
            s.append("response")
        if self.directions is not None:
            s.append("directions")
        if self.positions is not None and self.near_light:
            s.append("nearlight")
        if self.flat is not None:
            s.append("flat")
        if self.powers is not None:
            s.append("powers")
        if self.pixel_size is not None:
            s.append("pixelsize")
        return s


def apply_calibration(images, calib, *, dark=None, steps=None):
    """Apply a calibration: dark -> response -> flat / near light -> powers.

    Parameters
    ----------
    images : (k, H, W) float
        Raw images in [0, 1].
    calib : Calibration
    dark : (H, W) float, optional
        A dark frame taken with these images; its hot pixels (at the calibration's
        threshold) are added to the calibration's.
    steps : iterable of str, optional
        Restrict to these steps (``dark, response, flat, nearlight, powers``).

    Returns
    -------
    (k, H, W) float32
    """
    imgs = as_images(images)
    k, H, W = imgs.shape
    want = set(calib.steps() if steps is None else steps)
    if "dark" in want:
        hot = None if calib.hot is None else np.asarray(calib.hot, bool)
        if dark is not None:
            dh, _ = hot_pixels(dark, threshold=calib.hot_threshold)
            hot = dh if hot is None else (hot | dh)
        if hot is not None:
            if hot.shape != (H, W):
                raise PsbenchError(f"calibration hot-pixel map is {hot.shape}, images are {(H, W)}")
            imgs = remove_hot_pixels(imgs, hot)
    if "response" in want and calib.response is not None:
        imgs = apply_response(imgs, calib.response)
    if "flat" in want and calib.flat is not None:
        if calib.flat.shape != (H, W):
            raise PsbenchError(f"calibration flat field is {calib.flat.shape}, images are {(H, W)}")
        imgs = imgs / calib.flat[None].astype(np.float32)
    if "nearlight" in want and calib.positions is not None and calib.near_light:
        if calib.positions.shape[0] != k:
            raise PsbenchError(f"calibration has {calib.positions.shape[0]} light positions for {k} images")
        imgs = imgs / near_light_fields((H, W), calib.positions)
    if "powers" in want and calib.powers is not None:
        if calib.powers.shape != (k,):
            raise PsbenchError(f"calibration has {calib.powers.shape[0]} light powers for {k} images")
        imgs = imgs / calib.powers.astype(np.float32)[:, None, None]
    return np.ascontiguousarray(imgs, dtype=np.float32)


# --------------------------------------------------------------------------- corrections
@renamed_args(positional=("threshold",))
def hot_pixels(dark, *, threshold=None):
    """Hot pixels of a dark frame.

    Parameters
    ----------
    dark : (H, W) float
        Dark frame (all lights off), in [0, 1].
    threshold : float, optional
        Absolute threshold. Default: ``median + 8 * sigma`` of the frame with sigma
        estimated from the 1st-99th percentile range of the pixels (robust to the
        hot pixels themselves), and at least 0.05 above the median.

    Returns
    -------
    hot : (H, W) bool
    threshold : float
    """
    d = np.asarray(dark, dtype=np.float32)
    if d.ndim != 2:
        raise PsbenchError(f"dark must have shape (H, W), got {d.shape}")
    if threshold is None:
        med = float(np.median(d))
        lo, hi = np.percentile(d, [1, 99])
        core = d[(d >= lo) & (d <= hi)]
        sigma = float(core.std()) if core.size else 0.0
        threshold = med + max(8.0 * sigma, 0.05)
    return d > threshold, float(threshold)


@renamed_args(positional=("ksize",))
def remove_hot_pixels(images, hot, *, ksize=3):
    """Replace ``hot`` pixels in every image by the median of their neighbourhood.

    Parameters
    ----------
    images : (k, H, W) float32
    hot : (H, W) bool
    ksize : {3, 5}
        ``cv2.medianBlur`` aperture (float32 images allow 3 and 5).

    Returns
    -------
    (k, H, W) float32 (a copy)
    """
    import cv2
    imgs = as_images(images)
    hot = np.asarray(hot, bool)
    if hot.shape != imgs.shape[1:]:
        raise PsbenchError(f"hot must have shape {imgs.shape[1:]}, got {hot.shape}")
    if ksize not in (3, 5):
        raise PsbenchError(f"ksize must be 3 or 5, got {ksize}")
    out = imgs.copy()
    if not hot.any():
        return out
    for i in range(out.shape[0]):
        med = cv2.medianBlur(imgs[i], ksize)
        out[i][hot] = med[hot]
    return out


def _monotone_lut(coeffs, n=4097):
    grid = np.linspace(0.0, 1.0, n)
    v = np.maximum.accumulate(np.polyval(np.asarray(coeffs, dtype=np.float64), grid))
    return grid, v



def apply_response(images, coeffs):
    """Linearise images with the inverse response polynomial.

    The polynomial is tabulated on [0, 1] (4097 samples), made monotone by a running
    maximum and clipped at 0, then applied by linear interpolation.
    """
    grid, lut = _monotone_lut(coeffs)
    a = np.asarray(images, dtype=np.float64)
    out = np.interp(a, grid, np.maximum(lut, 0.0))
    return out.astype(np.float32)


def near_light_fields(shape, positions):
    """Rendered white planes for near lights, normalised to 1 at the image centre.

    Parameters
    ----------
    shape : (H, W)
    positions : (k, 3) float
        Light positions (pixel units, origin at the image centre on the datum).

    Returns
    -------
    (k, H, W) float32
        Plane image i (Lambert, inverse-square falloff) / its value at the origin.
    """
    from ..render.scene import render
    from ..surfaces import surface_from_height

    P = np.asarray(positions, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise PsbenchError(f"positions must have shape (k, 3), got {P.shape}")
    H, W = shape
    plane = surface_from_height(np.zeros((H, W)))
    d = P / np.linalg.norm(P, axis=1)[:, None]
    sc = render(plane, d, model="lambert", light_positions=P, falloff=True, shadows=False)
    # render's falloff is 1 at the origin, where the plane's shading is cos(zenith)
    return (sc.images / d[:, 2].astype(np.float32)[:, None, None]).astype(np.float32)


# --------------------------------------------------------------------------- folder
def save_calibration(calib, path, *, overwrite=True):
    """Write ``calibration.json`` + ``.npy`` arrays into the folder ``path`` atomically."""
    doc = {"format": "psbench-calibration", "version": 1, "steps": calib.steps(),
           "flat_degree": int(calib.flat_degree), "near_light": bool(calib.near_light),
           "response": None if calib.response is None else [float(c) for c in calib.response],
           "hot_threshold": calib.hot_threshold, "pixel_size_mm": calib.pixel_size,
           "meta": calib.meta, "arrays": {}}
    with atomic_dir(path, overwrite=overwrite) as tmp:
        for name in _ARRAYS:
            a = getattr(calib, name)
            if a is not None:
                np.save(tmp / f"{name}.npy", np.asarray(a))
                doc["arrays"][name] = f"{name}.npy"
        if calib.directions is not None:
            doc["directions"] = np.asarray(calib.directions).tolist()
        if calib.powers is not None:
            doc["powers"] = np.asarray(calib.powers).tolist()
        (tmp / "calibration.json").write_text(json.dumps(doc, indent=1, default=json_default))
    return Path(path)


def load_calibration(path):
    """Read a calibration folder (or its ``calibration.json``)."""
    p = Path(path)
    folder = p.parent if p.is_file() else p
    jf = p if p.is_file() else p / "calibration.json"
    if not jf.is_file():
        raise PsbenchError(f"calibration {str(p)!r}: no calibration.json")
    try:
        doc = json.loads(jf.read_text())
    except json.JSONDecodeError as e:
        raise PsbenchError(f"{jf}: invalid JSON ({e})") from None
    if doc.get("format") != "psbench-calibration":
        raise PsbenchError(f"{jf}: not a psbench calibration file")
    kw = {}
    for name, fn in doc.get("arrays", {}).items():
        f = folder / fn
        if not f.is_file():
            raise PsbenchError(f"calibration {jf}: array file {fn} is missing")
        kw[name] = np.load(f)
    if kw.get("hot") is not None:
        kw["hot"] = kw["hot"].astype(bool)
    resp = doc.get("response")
    return Calibration(response=None if resp is None else np.array(resp, float),
                       flat_degree=int(doc.get("flat_degree", 4)),
                       near_light=bool(doc.get("near_light", True)),
                       hot_threshold=doc.get("hot_threshold"),
                       pixel_size=doc.get("pixel_size_mm"), meta=doc.get("meta", {}), **kw)
