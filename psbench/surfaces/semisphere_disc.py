"""``semisphere_disc``: the hemisphere of :mod:`psbench.surfaces.semisphere` without its
ground plane: the object mask is the hemisphere's disc (psbench's ``semisphere`` before
the plane was added; e.g. the calibration sphere of the simulated rig)."""
from __future__ import annotations

from ..registry import SurfaceSpec
from .semisphere import semisphere


def semisphere_disc(size):
    """The hemisphere's disc on a (size, size) grid; the background is not object."""
    return semisphere(size, plane=False)


SURFACE = SurfaceSpec("semisphere_disc", semisphere_disc,
                      help="hemisphere of radius 0.45 size; object = its disc only")
