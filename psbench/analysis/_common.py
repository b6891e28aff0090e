"""Helpers shared by the analyses of :mod:`psbench.analysis` (scenes, solves, bins)."""
from __future__ import annotations

import numpy as np

from .._shared.checks import PsbenchError, choice
from .._shared.deprecation import renamed_names

__all__ = ["IMAGE_KINDS"]

#: image kinds (the ``kind=`` of the analyses) -> render options (formerly ``KINDS``)
IMAGE_KINDS = {"Di": dict(model="lambert", shadows="none"),
         "Di-clamped": dict(model="lambert", shadows="self"),
         "Hi-Sh": dict(model="ts", shadows=True)}


# ----------------------------------------------------------------------------- helpers
def _surface(surface, size):
    from ..surfaces import make_surface
    if isinstance(surface, str):
        return make_surface(surface, size=size)
    if all(hasattr(surface, a) for a in ("height", "object_mask", "normals")):
        return surface
    raise PsbenchError(f"surface must be a surface name or a Surface, got {type(surface).__name__}")


def _sname(surf, given):
    return given if isinstance(given, str) else getattr(surf, "name", "custom")


def _seq(x):
    if isinstance(x, (str, bytes)) or np.isscalar(x):
        return [x]
    return list(x)


def _render(surf, lights, kind, noise, seed, **kw):
    from ..render.scene import render
    opts = dict(IMAGE_KINDS[choice(kind, tuple(IMAGE_KINDS), "kind")])
    opts.update(kw)
    return render(surf, lights, noise=noise, seed=seed, **opts)


def _ne(normals, surf):
    from ..metrics.errors import normal_error
    return float(normal_error(normals, surf.normals, object_mask=surf.object_mask))


def _ps(images, lights, mask="None", **kw):
    from ..solve.api import solve
    return solve(images, lights, mask=mask, **kw)


def _ring(zenith, count):
    return f"{zenith:g}x{int(count)}"


def _surface_zenith(surf):
    n = np.asarray(surf.normals, dtype=np.float64)
    return np.degrees(np.arccos(np.clip(n[..., 2] / np.linalg.norm(n, axis=-1), -1, 1)))


def _edges(bins):
    if bins is None:
        return np.linspace(0.0, 90.0, 19)
    if np.isscalar(bins):
        return np.linspace(0.0, 90.0, int(bins) + 1)
    e = np.asarray(bins, dtype=float)
    if e.ndim != 1 or e.size < 2 or np.any(np.diff(e) <= 0):
        raise PsbenchError(f"bins must be an int or increasing edges, got {bins!r}")
    return e


__getattr__ = renamed_names(globals(), {"KINDS": "IMAGE_KINDS"})
