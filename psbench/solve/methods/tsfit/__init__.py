"""``tsfit``: the per-pixel Lambert + Torrance-Sparrow fit (module
:mod:`~psbench.solve.methods.tsfit.method`, where its decisions are documented).

Private parts: the compiled Levenberg-Marquardt kernels (``_kernel``, ``_aux_kernel``),
the step and its algebra (``_lm``), the starts (``_start``), the hemisphere grid
(``_grid``), the neighbour propagation (``_prop``) and the specular lobe shared by the
whole object (``_shared_lobe``).
"""
from .method import METHOD, TsfitOptions, tsfit

__all__ = ["TsfitOptions", "tsfit", "METHOD"]
