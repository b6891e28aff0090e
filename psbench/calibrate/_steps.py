"""Calibration-folder steps: read target captures, fit, store (``psbench-calibrate``).

Each ``step_*`` reads one target folder with :mod:`psbench.io`, runs the matching
function of :mod:`psbench.calibrate._fit` and updates a :class:`Calibration`;
:func:`calibrate_folder` runs them all on a capture's ``calibration_raw/`` folder.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError
from ..io import load_calibration, read_dataset, read_image, save_calibration
from ..io._calibration import Calibration, apply_calibration
from ._fit import (chart_means, fit_response, flat_field, hot_pixels, light_directions_from_sphere,
                   light_positions, light_powers, near_light_fields, pixel_size, sphere_geometry)

__all__ = ["step_dark", "step_response", "step_directions", "step_white", "step_pixelsize",
           "calibrate_folder", "load_or_new"]


def _read_folder_images(folder):
    """A target folder's raw images (no calibration applied) and its dark frame."""
    ds = read_dataset(folder, calibration="none")
    dark = None
    dp = Path(folder) / "dark.png"
    if dp.is_file():
        dark = read_image(dp, bits=ds.meta.get("bits") if ds.meta.get("bits") != 8 else None)
    return ds, dark


def _single(folder):
    """The first numbered image of a target folder (or the file itself) and its metadata."""
    folder = Path(folder)
    meta = {}
    if (folder / "psbench.json").is_file():
        meta = json.loads((folder / "psbench.json").read_text())
    imgs = sorted(folder.glob("[0-9]*.png"))
    if folder.is_file():
        return read_image(folder), meta
    if not imgs:
        raise PsbenchError(f"{folder}: no image")
    return read_image(imgs[0]), meta


def step_dark(calib, dark, threshold=None):
    """Hot pixels of the dark frame ``dark`` (H, W) into ``calib`` (Section 6.5.3)."""
    hot, thr = hot_pixels(dark, threshold=threshold)
    calib.hot, calib.hot_threshold = hot, thr
    calib.meta["dark"] = {"hot_pixels": int(hot.sum()), "threshold": thr}
    return calib


def step_response(calib, chart_folder, degree=6):
    """Inverse camera response from a gray-chart folder (Section 6.5.2).

    The folder's ``psbench.json`` lists the patch ``boxes`` and their ``radiance``.
    """
    img, meta = _single(chart_folder)
    if "boxes" not in meta or "radiance" not in meta:
        raise PsbenchError(f"{chart_folder}: psbench.json must list chart 'boxes' and 'radiance'")
    img = apply_calibration(img[None], calib, steps=["dark"])[0]
    m = chart_means(img, meta["boxes"])
    calib.response = fit_response(m, meta["radiance"], degree=degree)
    calib.meta["response"] = {"degree": int(calib.response.size - 1), "measured": m.tolist(),
                              "radiance": list(meta["radiance"])}
    return calib


def step_directions(calib, sphere_folder, *, distance=None, fraction=0.8, center=None,
                    radius=None):
    """Light directions (and, with ``distance``, positions) from a specular-sphere folder.

    The sphere's silhouette is the folder's ``mask.png``, or ``center`` and ``radius``
    (Section 6.3).
    """
    ds, dark = _read_folder_images(sphere_folder)
    imgs = apply_calibration(ds.images, calib, dark=dark, steps=["dark", "response"])
    has_mask = (Path(sphere_folder) / "mask.png").is_file()
    if not has_mask and (center is None or radius is None):
        raise PsbenchError(f"{sphere_folder}: no mask.png; give the sphere --center X Y and --radius R")
    silhouette = ds.object_mask if has_mask else None
    d, n, pts = light_directions_from_sphere(imgs, object_mask=silhouette, center=center,
                                             radius=radius, fraction=fraction)
    calib.directions = d
    if has_mask:
        cx, cy, R = sphere_geometry(silhouette)
    if center is not None:
        cx, cy = center
    if radius is not None:
        R = float(radius)
    if distance is None:
        distance = ds.meta.get("distance_px")
    calib.meta["sphere"] = {"center": [cx, cy], "radius": R, "distance_px": distance}
    if distance is not None:
        P = light_positions(d, n, float(distance), center=(cx, cy), radius=R)
        calib.positions = P
        calib.directions = P / np.linalg.norm(P, axis=1)[:, None]
    return calib


def step_white(calib, white_folder, *, degree=4, flat=True, powers=True):
    """Flat field (Section 6.5.1) and/or light powers (6.4) from a white-target folder."""
    ds, dark = _read_folder_images(white_folder)
    imgs = apply_calibration(ds.images, calib, dark=dark, steps=["dark", "response"])
    near = None
    if calib.positions is not None and calib.near_light:
        near = near_light_fields(imgs.shape[1:], calib.positions)
    if flat:
        calib.flat = flat_field(imgs, degree=degree, near=near)
        calib.flat_degree = int(degree)
    if powers:
        dirs = calib.directions if calib.directions is not None else ds.lights.directions
        calib.powers = light_powers(imgs, dirs, flat=calib.flat, near=near)
    return calib


def step_pixelsize(calib, grid_folder, pitch=None):
    """Pixel size from a grid-target folder of known ``pitch`` (mm; Section 6.6)."""
    img, meta = _single(grid_folder)
    pitch = meta.get("pitch_mm") if pitch is None else pitch
    if pitch is None:
        raise PsbenchError(f"{grid_folder}: give the grid pitch (mm) with --pitch")
    img = apply_calibration(img[None], calib, steps=["dark", "response"])[0]
    calib.pixel_size = pixel_size(img, float(pitch))
    return calib


def calibrate_folder(capture, out=None, *, raw=None, distance=None, flat_degree=4,
                     response_degree=6, threshold=None, near_light=True):
    """Run every step on a capture folder with ``calibration_raw/`` targets.

    Parameters
    ----------
    capture : folder of the object capture (its ``dark.png`` is the dark frame)
    out : calibration folder (default ``<capture>/calibration``)
    raw : folder with ``sphere/ white/ chart/ grid/`` (default ``<capture>/calibration_raw``)

    Returns
    -------
    Calibration
    """
    cap = Path(capture)
    raw = cap / "calibration_raw" if raw is None else Path(raw)
    out = cap / "calibration" if out is None else Path(out)
    calib = Calibration(near_light=near_light)
    dp = cap / "dark.png"
    if dp.is_file():
        step_dark(calib, read_image(dp), threshold)
    if (raw / "chart").is_dir():
        step_response(calib, raw / "chart", response_degree)
    if (raw / "sphere").is_dir():
        step_directions(calib, raw / "sphere", distance=distance)
    if (raw / "white").is_dir():
        step_white(calib, raw / "white", degree=flat_degree)
    if (raw / "grid").is_dir():
        step_pixelsize(calib, raw / "grid")
    calib.meta["source"] = str(cap)
    save_calibration(calib, out)
    return calib


def load_or_new(path):
    """The calibration in folder ``path``, or a new empty one when there is none."""
    p = Path(path)
    return load_calibration(p) if (p / "calibration.json").is_file() else Calibration()
