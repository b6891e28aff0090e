"""Calibration folders: ``calibration.json`` plus ``.npy`` arrays, written atomically.

The folder holds ``calibration.json`` (steps, parameters, response coefficients, pixel
size, provenance) and ``directions.npy``, ``positions.npy``, ``powers.npy``,
``flat.npy``, ``hot.npy`` as present.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError
from ..calibrate._calibration import Calibration
from ._common import json_default
from ._write import atomic_dir

__all__ = ["save_calibration", "load_calibration"]

_ARRAYS = ("directions", "positions", "powers", "flat", "hot")


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
