"""Unified photometric stereo: masked least squares, weighted PS, subset methods.

``solve`` (see :mod:`psbench.solve.api`) is the entry point; every per-pixel solve
goes through the WLS kernel of :mod:`psbench.solve.kernel`.
"""
from .api import MASKS, METHODS, Result, solve

__all__ = ["solve", "Result", "MASKS", "METHODS"]
