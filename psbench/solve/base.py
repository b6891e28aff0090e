"""The contracts between :func:`psbench.solve`, its masks and its methods.

A **method** (``psbench.methods`` entry point, :class:`psbench.registry.Method`) is

    func(problem: Problem, options: <its Options dataclass>) -> Fit

``problem.valid`` holds the observations the mask expression kept (all True for
``mask="None"``); a robust method uses only those (it may drop more, and reports what it
used in ``Fit.valid`` / ``Fit.weights``). ``problem.start()`` gives the masked
least-squares solution (computed once, on first use), a natural starting point.

A method's options class subclasses :class:`Options` (the options of the mask engine:
``max_iter``, ``iter_tol``, ``th_scope``, ...), adds its own fields with defaults,
documents each in its numpydoc docstring and validates them in ``__post_init__``
(call ``super().__post_init__()``), raising :class:`psbench.PsbenchError` with a
one-line message naming the option and the valid range.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Callable

import numpy as np

from .._checks import PsbenchError

__all__ = ["Options", "Problem", "Fit", "check_int", "check_number", "check_choice"]


def check_int(value, name, *, lo=None, hi=None):
    """An integer option in [lo, hi] (bools refused)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise PsbenchError(f"{name} must be an integer, got {value!r}")
    if (lo is not None and value < lo) or (hi is not None and value > hi):
        raise PsbenchError(f"{name} must be an integer in [{lo if lo is not None else '-inf'}, "
                           f"{hi if hi is not None else 'inf'}], got {value!r}")
    return int(value)


def check_number(value, name, *, lo=None, hi=None, lo_open=False, hi_open=False,
                 allow_none=False):
    """A finite real option within the given bounds (open or closed)."""
    if value is None and allow_none:
        return None
    ok = (not isinstance(value, bool) and isinstance(value, (int, float, np.integer, np.floating))
          and np.isfinite(value))
    if ok and lo is not None:
        ok = value > lo if lo_open else value >= lo
    if ok and hi is not None:
        ok = value < hi if hi_open else value <= hi
    if not ok:
        lb = "(" if lo_open else "["
        rb = ")" if hi_open else "]"
        rng = f"{lb}{lo if lo is not None else '-inf'}, {hi if hi is not None else 'inf'}{rb}"
        extra = " or None" if allow_none else ""
        raise PsbenchError(f"{name} must be a number in {rng}{extra}, got {value!r}")
    return float(value)


def check_choice(value, valid, name):
    if value not in valid:
        raise PsbenchError(f"{name}={value!r} is not known; valid choices: "
                           f"{', '.join(map(str, valid))}")
    return value


@dataclass
class Options:
    """Options of the mask engine, shared by every masked method.

    Parameters
    ----------
    max_iter : int
        Maximum PS <-> normal-mask rounds (Fig. 3.1 steps 5-6); >= 0.
    iter_tol : float
        Also stop after a round that changed the mask of at most this fraction of
        the object pixels; in [0, 1). 0: iterate until nothing changes, a cycle, or
        ``max_iter``.
    th_scope : {"image", "object", "robust", "pixel"}
        Where the dynamic ranges of Th / Hi / CS come from; "image" is the thesis's
        rule (Eq. 3.2).
    th_offset : bool
        Offset the Th bounds by i_min (False: literal Eq. 3.2).
    sh_bias : float or None
        Shadow-map bias of the Sh mask (None: the shadow map's default).
    integrate_method : {"poisson", "fc"}
        Integrator used by Sh and ``want_height``.
    n_subsets : int or None
        Triplets drawn by RA (None: Eq. 3.11).
    weighted : bool
        Weighted masks (Section 3.4.2, Eq. 3.19) after the binary masked solve.
    dilate_radius, smooth_sigma, kernel_size, sigma_min
        Weighted-mask parameters (disk radius 7, Gaussian sigma 3, 15x15 kernels,
        sigma_min None = 1 % of the mean dynamic range).
    """

    max_iter: int = 10
    iter_tol: float = 1e-3
    th_scope: str = "image"
    th_offset: bool = False
    sh_bias: float | None = None
    integrate_method: str = "poisson"
    n_subsets: int | None = None
    weighted: bool = False
    dilate_radius: int = 7
    smooth_sigma: float = 3.0
    kernel_size: int = 15
    sigma_min: float | None = None

    def __post_init__(self):
        check_int(self.max_iter, "max_iter", lo=0)
        check_number(self.iter_tol, "iter_tol", lo=0, hi=1, hi_open=True)
        check_choice(self.th_scope, ("image", "object", "robust", "pixel"), "th_scope")
        if not isinstance(self.th_offset, (bool, np.bool_)):
            raise PsbenchError(f"th_offset must be true or false, got {self.th_offset!r}")
        check_number(self.sh_bias, "sh_bias", allow_none=True)
        check_choice(self.integrate_method, ("poisson", "fc"), "integrate_method")
        if self.n_subsets is not None:
            check_int(self.n_subsets, "n_subsets", lo=1)
        if not isinstance(self.weighted, (bool, np.bool_)):
            raise PsbenchError(f"weighted must be true or false, got {self.weighted!r}")
        check_int(self.dilate_radius, "dilate_radius", lo=0)
        check_int(self.kernel_size, "kernel_size", lo=1)
        if self.kernel_size % 2 == 0:
            raise PsbenchError(f"kernel_size must be odd and >= 1, got {self.kernel_size!r}")
        check_number(self.smooth_sigma, "smooth_sigma", lo=0)
        check_number(self.sigma_min, "sigma_min", lo=0, lo_open=True, allow_none=True)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    @classmethod
    def build(cls, values: dict | None = None, *, method: str = ""):
        """Options from a dict; unknown names are refused, listing the valid ones."""
        values = dict(values or {})
        valid = cls.names()
        bad = [k for k in values if k not in valid]
        if bad:
            who = f"method {method!r}" if method else cls.__name__
            raise PsbenchError(f"unknown option(s) {', '.join(map(repr, bad))} for {who}; "
                               f"valid options: {', '.join(valid)}")
        return cls(**values)


@dataclass(eq=False)
class Problem:
    """One solve, as a method sees it.

    Attributes
    ----------
    images : (k, H, W) float32
        Validated linear images.
    lights : Layout
    valid : (k, H, W) bool
        Observations the mask expression allows (True = may be used); after Eq. 3.1's
        completion, so every pixel keeps at least three.
    object_mask : (H, W) bool
    mask : str
        Canonical mask expression ("Th-Hi-Re-Sh", "None").
    thresholds : dict
        Resolved thresholds.
    scale : float
        Mean dynamic range of the images (> 0): a natural unit for residual scales.
    seed : int
    truth_normals : (H, W, 3) or None
        Diagnostics only.
    """

    images: np.ndarray
    lights: Any
    valid: np.ndarray
    object_mask: np.ndarray
    mask: str = "None"
    thresholds: dict = field(default_factory=dict)
    scale: float = 1.0
    seed: int = 0
    truth_normals: np.ndarray | None = None
    _start: Any = None
    engine: Callable | None = None

    @property
    def S(self) -> np.ndarray:
        """(k, 3) float64 illumination matrix."""
        return np.asarray(self.lights.S, dtype=np.float64)

    def start(self) -> np.ndarray:
        """Masked least-squares solution rho * n, (H, W, 3) float32 (cached)."""
        if callable(self._start):
            self._start = self._start()
        return self._start


@dataclass(eq=False)
class Fit:
    """What a method returns.

    Attributes
    ----------
    b : (H, W, 3) float32
        rho * n.
    valid : (k, H, W) bool or None
        Observations finally used (inliers); None: ``problem.valid``.
    weights : (k, H, W) float32 or None
        Final per-observation weights (1 = fully trusted, 0 = unused); None for
        binary solves.
    iterations : int or (H, W) int array
    converged : bool, str or (H, W) bool array
    info : dict
        Method-specific extras (stored in ``Result.info``).
    """

    b: np.ndarray
    valid: np.ndarray | None = None
    weights: np.ndarray | None = None
    iterations: Any = 0
    converged: Any = True
    info: dict = field(default_factory=dict)
