"""psbench: photometric stereo under highlights and shadows.

Public API (see README): ``make_surface``, ``surface_from_height``, ``layout``,
``render``, ``solve``, ``normal_error``, ``intensity_error``, ``quality_factor``,
``integrate``, ``cond`` and the ``io`` module. Names are imported lazily so that
``import psbench`` stays fast.
"""
from __future__ import annotations

import importlib

from ._checks import PsbenchError

__version__ = "0.1.0"

_EXPORTS = {
    "make_surface": "psbench.surfaces",
    "surface_from_height": "psbench.surfaces",
    "surface_from_file": "psbench.surfaces",
    "Surface": "psbench.surfaces",
    "SURFACES": "psbench.surfaces",
    "layout": "psbench.lights",
    "Layout": "psbench.lights",
    "cond": "psbench.lights",
    "render": "psbench.render",
    "Scene": "psbench.render",
    "shadow_map": "psbench.shadowmap",
    "solve": "psbench.solve",
    "Result": "psbench.solve",
    "normal_error": "psbench.metrics",
    "normal_error_stats": "psbench.metrics",
    "intensity_error": "psbench.metrics",
    "quality_factor": "psbench.metrics",
    "integrate": "psbench.integrate",
}
_MODULES = {"io", "calibrate", "capture", "metrics", "surfaces", "lights", "render",
            "shadowmap", "integrate", "analysis"}

__all__ = sorted(_EXPORTS) + sorted(_MODULES) + ["PsbenchError", "__version__"]


def __getattr__(name):
    if name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
        globals()[name] = value
        return value
    if name in _MODULES:
        mod = importlib.import_module(f"psbench.{name}")
        globals()[name] = mod
        return mod
    raise AttributeError(f"module 'psbench' has no attribute {name!r}")
