"""Synthetic images with ground truth: shading models, shadow maps, interreflections.

:func:`render` (module :mod:`~psbench.render.scene`) is the entry point; cast shadows
come from :mod:`~psbench.render.shadowmap`. The private modules hold the shading models
(``_shading``), the compiled kernels (``_shadowmap_kernel``, ``_interreflect_kernel``)
and the interreflection bounces (``_interreflect*``).
"""
from .scene import (HIGHLIGHT_ANGLE, HIGHLIGHT_FRACTION, HIGHLIGHT_RULES, MODELS, SHADOWS, Scene,
                    render)
from .shadowmap import light_directions, point_shadow_map, shadow_map

__all__ = ["render", "Scene", "MODELS", "SHADOWS", "HIGHLIGHT_RULES", "HIGHLIGHT_ANGLE",
           "HIGHLIGHT_FRACTION", "shadow_map", "point_shadow_map", "light_directions"]
