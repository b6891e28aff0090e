"""Weighted multi-zenith photometric stereo (WPS, thesis Section 4.3): the method
(``METHOD``, module :mod:`~psbench.solve.methods.wps.method`, where its decisions are
documented), its ring weights (``_weights``) and compiled kernels (``_kernel``,
``_math``), and :func:`wps`, the function form of ``solve(..., method="wps")``.
"""
from __future__ import annotations

from ._weights import DEFAULT_WEIGHT, WEIGHTS, fuse, oracle_weights, sig, surface_factor
from .method import METHOD, WPSOptions, WPSResult

__all__ = ["wps", "WEIGHTS", "DEFAULT_WEIGHT", "sig", "surface_factor", "oracle_weights",
           "fuse", "WPSResult", "WPSOptions", "METHOD"]


def wps(images, lights, *, weight=DEFAULT_WEIGHT, binary=False, mask="None", **kwargs):
    """Weighted multi-zenith PS: ``solve(images, lights, method="wps", ...)``.

    Parameters
    ----------
    images : (k, H, W) array_like
    lights : Layout, ring notation or (k, 3) array_like
        At least two rings (ring ids of the Layout; explicit directions are grouped by
        zenith), each with at least 3 lights.
    weight : {"eZsourceZsurface", "eZsurface", "eZsource", "e", "oracle", "None"}
        Weight definition; None = the default.
    binary : bool
        Eq. 4.12: select the ring with the largest weight instead of blending.
    mask : str
        Mask applied to each ring's solve ("None": one least-squares product).
    **kwargs
        Any other keyword of :func:`psbench.solve` (``object_mask``, ``truth_normals``
        -- needed by ``weight="oracle"`` --, ``thresholds``, ``seed``, ``weighted``,
        ``max_iter``, ``want_height``, ``z_scale``, mask-engine options).

    Returns
    -------
    WPSResult
        ``ring_weights (rings, H, W)``, ``ring_normals (rings, H, W, 3)``,
        ``ring_albedo``, ``ring_residual (rings, H, W)`` (RMS e_j) besides the
        :class:`~psbench.solve.Result` fields.
    """
    from ...api import solve
    return solve(images, lights, method="wps", weight=weight, binary=binary, mask=mask, **kwargs)
