"""psbench: photometric stereo under highlights and shadows.

Public API (see README): ``make_surface``, ``surface_from_height``, ``layout``,
``render``, ``solve``, ``normal_error``, ``intensity_error``, ``quality_factor``,
``integrate``, ``cond`` and the ``io`` module.

The core functions are imported eagerly: ``render``, ``solve`` and ``integrate`` share
their names with the modules that define them, and a lazy export would be shadowed by
the submodule as soon as it is imported. The heavier real-image modules (``io``,
``calibrate``, ``capture``, ``analysis``) load on first use. ``SURFACES`` lists the
registered surfaces (plug-ins included) each time it is read.
"""
from __future__ import annotations

import importlib

# first: numba's fork-safe threading layer
from ._shared import numba_setup as _numba_setup  # noqa: F401
from . import surfaces
from ._shared.checks import PsbenchError
from ._shared.deprecation import MOVED, moved_modules
from .integrate import integrate
from .lights import Layout, cond, layout
from .metrics import (intensity_error, normal_error, normal_error_map, normal_error_stats,
                      quality_factor)
from .render import Scene, render, shadow_map
from .solve import Result, solve
from .surfaces import (Surface, Topography, make_surface, surface_from_file, surface_from_height,
                       surface_from_topography)

moved_modules()  # old paths of moved public modules, one release behind a warning

__version__ = "0.1.0"

_LAZY = {"io", "calibrate", "capture", "analysis", "harness", "report"}

__all__ = ["PsbenchError", "__version__", "integrate", "Layout", "cond", "layout",
           "intensity_error", "normal_error", "normal_error_map", "normal_error_stats",
           "quality_factor", "Scene", "render", "shadow_map", "Result", "solve", "SURFACES",
           "Surface", "make_surface", "surface_from_file", "surface_from_height",
           "Topography", "surface_from_topography",
           *sorted(_LAZY)]


def __getattr__(name):
    if name == "SURFACES":  # read from the surface registry on every access
        return surfaces.SURFACES
    if name in _LAZY or f"psbench.{name}" in MOVED:
        mod = importlib.import_module(f"psbench.{name}")
        globals()[name] = mod
        return mod
    raise AttributeError(f"module 'psbench' has no attribute {name!r}")
