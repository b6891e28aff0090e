"""The :class:`Calibration` record and :func:`apply_calibration` (no file I/O).

Calibration folders are read and written by :func:`psbench.io.load_calibration` and
:func:`psbench.io.save_calibration`.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._shared.checks import PsbenchError, as_images
from ._fit import apply_response, hot_pixels, near_light_fields, remove_hot_pixels

__all__ = ["Calibration", "apply_calibration"]


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
