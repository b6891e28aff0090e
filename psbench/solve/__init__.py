"""Unified photometric stereo: masked least squares, weighted PS, subset methods, WPS.

:func:`solve` is the entry point: a mask expression of registered **masks**
(``psbench.masks`` entry points; built-ins in :mod:`psbench.solve.masks`, one module
per mask) runs before a registered **method** (``psbench.methods``; built-ins in
:mod:`psbench.solve.methods`: ps, fwlse, wps), and every per-pixel solve goes through
the WLS kernel of :mod:`psbench.solve.kernel`.

The contracts a mask function and a method follow (stages image / subset / normal,
the :class:`~psbench.solve.base.Context` a mask receives, the
:class:`~psbench.solve.base.Problem` -> :class:`~psbench.solve.base.Fit` of a method,
and the :class:`~psbench.solve.base.Options` a method's options subclass) are in
:mod:`psbench.solve.base`.

``MASKS`` and ``METHODS`` are read from the registries when accessed.
"""
from .api import Result, parse_mask, solve
from .base import Context, Fit, Options, Problem

__all__ = ["solve", "Result", "MASKS", "METHODS", "parse_mask", "Options", "Problem", "Fit",
           "Context"]


def __getattr__(name):
    if name in ("MASKS", "METHODS"):
        from . import api
        return getattr(api, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
