"""Shared pieces of :mod:`psbench.io`: the warning type, luma weights, JSON encoding."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["PsbenchWarning", "LUMA", "IMAGE_EXT", "cv2", "json_default"]

#: BT.601 luma weights (R, G, B)
LUMA = np.array([0.299, 0.587, 0.114])
#: image file extensions psbench reads and writes
IMAGE_EXT = (".png", ".tif", ".tiff")


class PsbenchWarning(UserWarning):
    """Input was accepted after a correction (e.g. renormalised light directions)."""


def cv2():
    """OpenCV, imported on first use."""
    import cv2 as _cv2
    return _cv2


def json_default(o):
    """``json.dumps(default=...)`` for numpy arrays and scalars and paths."""
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, (np.floating,)):
        return float(o)
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o)}")

