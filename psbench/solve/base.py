"""The contracts between :func:`psbench.solve`, its masks and its methods.

:func:`psbench.solve` runs Fig. 3.1 of the thesis as a pipeline of registered pieces:

1. the **mask expression** (``"Th-Hi-Re-Sh"``) is parsed against the ``psbench.masks``
   registry; the thresholds every registered mask declares are resolved for the image
   count (:func:`psbench.solve.thresholds.resolve_thresholds`);
2. for a masked method, the **mask engine** runs the subset and image masks, the first
   least-squares solve (Eq. 3.1's completion keeps three observations per pixel) and
   the PS <-> normal-mask rounds;
3. the **method** computes rho * n from a :class:`Problem`; the weighted-mask step
   (Eq. 3.19) follows when ``weighted=True``; the :class:`~psbench.solve.Result` is
   assembled.

Masks
-----
A mask is a :class:`psbench.registry.Mask` whose ``func`` follows its stage's contract.
Every mask function receives a :class:`Context` ``ctx`` and returns **validity**, a
new bool array (True = observation used; the engine may modify it in place):

=======================  ==============================================================
stage                    contract
=======================  ==============================================================
``"image"``              ``func(images, ctx) -> valid``; images (k, H, W) float32,
                         valid (k, H, W) bool (Th, NL)
``"subset"``             same signature (xNL, RA)
``"subset"``, fuses      ``func(images, ctx) -> (b, valid)``: its own fused solution
                         b (H, W, 3) float32 and the observations it used (CJ); cannot
                         be combined with other masks
``"normal"``, local      ``func(images, b, ctx) -> valid`` on **flat** arrays: images
                         (k, n) float32, b (n, 3) float32 (rho * n), valid (k, n) bool.
                         It depends on each pixel's own solution only, so after the
                         first round the engine passes only the pixels whose solution
                         changed (``ctx.pixels`` holds their flat indices; None = all
                         pixels in order) (SS, Re, CS, Hi)
``"normal"``, global     ``func(images, b, ctx) -> valid`` on full arrays: images
                         (k, H, W), b (H, W, 3), valid (k, H, W); evaluated on every
                         pixel each round (``local=False``: Sh, which integrates the
                         normals into heights)
``"normal"``, global,    ``func(images, b, ctx) -> (valid, correction)``: also a
corrects                 per-observation **correction** (k, H, W) float32 (or None:
                         nothing to correct this round), light the images hold that
                         the Lambert model does not explain (SR: the predicted
                         secondary light); see *Corrections* below
=======================  ==============================================================

Validities are ANDed; where fewer than three observations remain, Eq. 3.1 adds back
the masked ones of least unmasked-LS residual. A mask reads its thresholds from
``ctx.thresholds[name]`` (declared in ``Mask.thresholds``, so users can override them
with ``solve(..., thresholds={name: value})``); a mask that reads ``ctx.ranges`` or
``ctx.scale`` declares ``ranges=True`` (a local normal mask reads them through
``ctx.flat_ranges()``, shaped for its flat arrays). ``ctx.cache`` is emptied before each stage
evaluation: masks of one evaluation share work through it (Hi and CS share one
Lambert residual); ``ctx.state`` lives for the whole solve (a mask that iterates keeps
its own state across rounds under its name).

Corrections
-----------
Masking cannot remove an error every observation shares (Lambertian interreflection
adds light to each lit observation that is linear in the light direction: the lit
observations agree on a wrong normal). A global normal mask may therefore also return
a correction ``c`` (k, H, W) float32 (the tuple form above). The engine then works on
the **corrected images** ``J = images - c`` (the corrections of several masks add up):

* every mask judges the corrected images: in each round, as soon as the correction is
  known, the image and subset masks are evaluated again on ``J`` (with the dynamic
  ranges ``ctx.ranges`` measured again on ``J`` when the solve measures ranges); the
  local normal masks of the next round see ``J`` with the solution computed from it;
  a global mask's ``images`` argument is ``J`` of the previous round (the input images
  in the first round); ``ctx.images`` stays the input images (a correcting mask
  compares its correction with the observations there);
* the PS solves, Eq. 3.1's completion (its residual order recomputed on ``J``), the
  method (``Problem.images`` is ``J``), the weighted-mask step and ``Result.residual``
  use ``J``;
* each round returns a new correction (not an increment): ``J = images - c`` is
  recomputed from the input images, and pixels whose ``J`` changed are solved again;
* the rounds stop when the valid masks change at no more than ``iter_tol`` of the
  object pixels **and** the mean normal change of the round is below ``correct_tol``
  degrees (or after ``max_iter`` rounds); no cycle detection (the corrections are
  real-valued). ``Result.info`` holds ``correction`` (the last one, (k, H, W)
  float32) and ``change`` (mean normal change per round, degrees).

A mask that returns a plain validity never enters this path: without corrections the
engine runs exactly as before.

Methods
-------
A **method** (``psbench.methods`` entry point, :class:`psbench.registry.Method`) is

    func(problem: Problem, options: <its Options dataclass>) -> Fit

``problem.valid`` holds the observations the mask expression kept (all True for
``mask="None"``); a robust method uses only those (it may drop more, and reports what it
used in ``Fit.valid`` / ``Fit.weights``). ``problem.start()`` gives the masked
least-squares solution (computed once, on first use), a natural starting point.
A method registered with ``masked=False`` runs the masks itself: ``problem.valid`` is
then all True (read-only) and ``problem.engine(images, lights)`` runs this solve's
mask expression and options on any subset of the observations (WPS: once per ring).

A method's options class subclasses :class:`Options` (the options of the mask engine:
``max_iter``, ``iter_tol``, ``th_scope``, ...), adds its own fields with defaults,
documents each in its numpydoc docstring and validates them in ``__post_init__``
(call ``super().__post_init__()``), raising :class:`psbench.PsbenchError` with a
one-line message naming the option and the valid range. A method that reads
``problem.scale`` may set the class attribute ``needs_ranges = True`` so the ranges
are measured once, before the masks (FWLSE does; otherwise they are measured on first
read).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Callable, ClassVar

import numpy as np

from .._shared.checks import PsbenchError
from .._shared.deprecation import warn_renamed

__all__ = ["Options", "Problem", "Fit", "Context", "Lazy", "check_int", "check_number",
           "check_choice", "check_bool"]

_MISSING = object()


class Lazy:
    """A dataclass field that may be given as a zero-argument function: it is called on
    first read and its value kept (for values that cost a pass over the images and that
    many callers never read, e.g. the unmasked residual map or the dynamic range)."""

    def __init__(self, default=_MISSING):
        self.default = default

    def __set_name__(self, owner, name):
        self.slot = "_lazy_" + name

    def __get__(self, obj, objtype=None):
        if obj is None:
            if self.default is _MISSING:
                raise AttributeError(self.slot)  # class access: the field has no default
            return self.default
        value = obj.__dict__[self.slot]
        if callable(value):
            value = value()
            obj.__dict__[self.slot] = value
        return value

    def __set__(self, obj, value):
        obj.__dict__[self.slot] = value


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


def check_bool(value, name):
    """A true/false option (numpy bools accepted)."""
    if not isinstance(value, (bool, np.bool_)):
        raise PsbenchError(f"{name} must be true or false, got {value!r}")
    return bool(value)


def check_choice(value, valid, name):
    """One of ``valid``; otherwise the error lists them."""
    if value not in valid:
        raise PsbenchError(f"{name}={value!r} is not known; valid choices: "
                           f"{', '.join(map(str, valid))}")
    return value


#: renamed options: old name -> new name (the old one warns, for one release)
RENAMED_OPTIONS = {"integrate_method": "integrator"}


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
    integrator : {"poisson", "fc"}
        Integrator used by Sh and ``want_height`` (formerly ``integrate_method``, which
        :meth:`build` and :func:`psbench.solve` still accept, with a warning).
    n_subsets : int or None
        Triplets drawn by RA (None: Eq. 3.11).
    weighted : bool
        Weighted masks (Section 3.4.2, Eq. 3.19) after the binary masked solve.
    dilate_radius, smooth_sigma, kernel_size, sigma_min
        Weighted-mask parameters (disk radius 7, Gaussian sigma 3, 15x15 kernels,
        sigma_min None = 1 % of the mean dynamic range).
    correct_tol : float
        With a correcting mask (SR, see *Corrections* in :mod:`psbench.solve.base`):
        stop only once a round moves the normals by less than this mean angle,
        degrees; >= 0.
    sr_samples : int
        SR: azimuths of the ray-casting quadrature (>= 4); the rounds in which the
        normals still move by more than 1 degree use half of them.
    sr_size : int or None
        SR: largest side of the prediction grid, pixels (>= 8; block means; the
        secondary light is smooth); None: full resolution.
    sr_damp : float
        SR: relaxation in [0, 1): from the second round on the correction is
        ``(1 - sr_damp) new + sr_damp previous`` (the fixed-point iteration can
        oscillate).
    sr_correct : bool
        SR: subtract the predicted secondary light (False: the thesis's mask alone).
    sr_bounces : {1, 2}
        SR: bounces of light predicted.
    sr_source : {"model", "images"}
        SR: emitters of the prediction: the predicted direct Lambert light, or the
        observed images (see :func:`psbench.solve.masks._sr.predict`).
    """

    max_iter: int = 10
    iter_tol: float = 1e-3
    th_scope: str = "image"
    th_offset: bool = False
    sh_bias: float | None = None
    integrator: str = "poisson"
    n_subsets: int | None = None
    weighted: bool = False
    dilate_radius: int = 7
    smooth_sigma: float = 3.0
    kernel_size: int = 15
    sigma_min: float | None = None
    correct_tol: float = 0.02
    sr_samples: int = 24
    sr_size: int | None = 128
    sr_damp: float = 0.5
    sr_correct: bool = True
    sr_bounces: int = 1
    sr_source: str = "model"

    #: the method reads ``problem.scale``: measure the ranges before the masks
    needs_ranges: ClassVar[bool] = False

    def __post_init__(self):
        check_int(self.max_iter, "max_iter", lo=0)
        check_number(self.iter_tol, "iter_tol", lo=0, hi=1, hi_open=True)
        check_choice(self.th_scope, ("image", "object", "robust", "pixel"), "th_scope")
        check_bool(self.th_offset, "th_offset")
        check_number(self.sh_bias, "sh_bias", allow_none=True)
        check_choice(self.integrator, ("poisson", "fc"), "integrator")
        if self.n_subsets is not None:
            check_int(self.n_subsets, "n_subsets", lo=1)
        check_bool(self.weighted, "weighted")
        check_int(self.dilate_radius, "dilate_radius", lo=0)
        check_int(self.kernel_size, "kernel_size", lo=1)
        if self.kernel_size % 2 == 0:
            raise PsbenchError(f"kernel_size must be odd and >= 1, got {self.kernel_size!r}")
        check_number(self.smooth_sigma, "smooth_sigma", lo=0)
        check_number(self.sigma_min, "sigma_min", lo=0, lo_open=True, allow_none=True)
        check_number(self.correct_tol, "correct_tol", lo=0)
        check_int(self.sr_samples, "sr_samples", lo=4)
        if self.sr_size is not None:
            check_int(self.sr_size, "sr_size", lo=8)
        check_number(self.sr_damp, "sr_damp", lo=0, hi=1, hi_open=True)
        check_bool(self.sr_correct, "sr_correct")
        check_int(self.sr_bounces, "sr_bounces", lo=1, hi=2)
        check_choice(self.sr_source, ("model", "images"), "sr_source")

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    @property
    def integrate_method(self):
        """Deprecated name of :attr:`integrator`."""
        warn_renamed("Options.integrate_method", "Options.integrator")
        return self.integrator

    @classmethod
    def build(cls, values: dict | None = None, *, method: str = ""):
        """Options from a dict; unknown names are refused, listing the valid ones."""
        values = dict(values or {})
        for old, new in RENAMED_OPTIONS.items():
            if old in values:
                if new in values:
                    raise PsbenchError(f"options {old} (deprecated) and {new} both given")
                warn_renamed(f"the option {old}", new, stacklevel=4)
                values[new] = values.pop(old)
        bad = [k for k in values if k not in cls.__dataclass_fields__]
        if bad:
            who = f"method {method!r}" if method else cls.__name__
            raise PsbenchError(f"unknown option(s) {', '.join(map(repr, bad))} for {who}; "
                               f"valid options: {', '.join(cls.names())}")
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
        completion, so every pixel keeps at least three. All True (read-only) for a
        method registered with ``masked=False``.
    object_mask : (H, W) bool
    mask : str
        Canonical mask expression ("Th-Hi-Re-Sh", "None").
    thresholds : dict
        Resolved thresholds.
    scale : float
        Mean dynamic range of the images (> 0; ``th_scope`` decides over which pixels):
        a natural unit for residual scales. Measured on first read unless the options
        class sets ``needs_ranges``.
    seed : int
    truth_normals : (H, W, 3) or None
        Diagnostics only.
    engine : callable or None
        ``engine(images, lights, *, truth_normals=None) -> Result``: this solve's mask
        expression, thresholds overrides and options run as masked least squares
        (subsets, image masks, PS <-> normal masks, weighted masks) on other images,
        e.g. one ring's; thresholds are resolved for their image count.
    """

    images: np.ndarray
    lights: Any
    valid: np.ndarray
    object_mask: np.ndarray
    mask: str = "None"
    thresholds: dict = field(default_factory=dict)
    scale: float = Lazy(1.0)
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
        if self._start is None:
            from .kernel import ls, wls
            v = self.valid
            self._start = ls(self.images, self.S) if v.all() else wls(self.images, self.S, v)
        elif callable(self._start):
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
        Method-specific extras (merged into ``Result.info``).
    residual : (H, W) float32 or None
        The method's own residual map of the final solution, when it has it exactly
        (WPS); None: computed over ``valid`` from ``b``.
    ring_weights : (rings, H, W) float32 or None
        Per-ring fusion weights (WPS, Eq. 4.9).
    timings : dict
        Stage -> seconds inside the method (merged into ``Result.timings``).
    fields : dict
        Further fields of ``result_type`` (WPS: ``ring_normals``, ...; may set
        ``thresholds``).
    result_type : type or None
        A :class:`~psbench.solve.Result` subclass to return (None: ``Result``).
    heldout : tuple or None
        ``(e, used, ve)``: the fit's held-out errors and used observations, (k, P)
        float32 and bool over the object pixels, and its per-pixel validation error
        (P,) float32 (:mod:`psbench.solve.validation`), for
        a method that starts from this fit and falls back to it
        (:mod:`psbench.solve.fallback`), or a function of no arguments returning it
        (assembled only when asked for); None: not computed.
    """

    b: np.ndarray
    valid: np.ndarray | None = None
    weights: np.ndarray | None = None
    iterations: Any = 0
    converged: Any = True
    info: dict = field(default_factory=dict)
    residual: np.ndarray | None = None
    ring_weights: np.ndarray | None = None
    timings: dict = field(default_factory=dict)
    fields: dict = field(default_factory=dict)
    result_type: type | None = None
    heldout: Any = None


@dataclass(eq=False)
class Context:
    """What a mask function sees (see the stage contracts above).

    Attributes
    ----------
    images : (k, H, W) float32
        All images of the solve (the stage's own ``images`` argument may be a flat
        subset of them).
    lights : Layout
    tokens : tuple of str
        Canonical mask names of the expression (``("Th", "Hi", "Re", "Sh")``): a mask may
        adapt to its company (NL-Re).
    thresholds : dict
        Resolved thresholds (every registered mask's, overrides applied).
    options : Options
        The method's options (``th_scope``, ``sh_bias``, ``n_subsets``, ...).
    object_mask : (H, W) bool
    seed : int
    ranges : dict or None
        Dynamic ranges (:func:`psbench.solve.masks.ranges`: ``lo``, ``rng``, ``lo_up``,
        ``rng_up`` (k, 1, 1) or (1, H, W), ``scale``, ``dead``), measured before the
        masks when any stage declared that it reads them, else None.
    cache : dict
        Emptied by the engine before each stage evaluation; shared by the masks of one
        evaluation.
    state : dict
        Kept for the whole solve: a mask that iterates (SR) keeps its state across
        rounds here, under its name.
    pixels : (n,) int array or None
        Local normal stage: flat pixel indices of the columns passed (None: all).
    warnings : list of str
        Messages also stored in ``Result.info["warnings"]``.
    """

    images: np.ndarray
    lights: Any
    tokens: tuple
    thresholds: dict
    options: Options
    object_mask: np.ndarray
    seed: int = 0
    ranges: dict | None = None
    cache: dict = field(default_factory=dict)
    state: dict = field(default_factory=dict)
    pixels: np.ndarray | None = None
    warnings: list = field(default_factory=list)

    def __post_init__(self):
        self.S = self.lights.S.astype(np.float64)
        self.S32 = self.S.astype(np.float32)
        self.directions = self.lights.directions
        self.full = bool(self.object_mask.all())
        self._flat = None

    @property
    def k(self) -> int:
        return self.images.shape[0]

    @property
    def region(self):
        """``object_mask``, or None when it selects every pixel (cheaper paths)."""
        return None if self.full else self.object_mask

    @property
    def scale(self) -> float:
        """Mean dynamic range of the images when ``ranges`` were measured, else 1."""
        return self.ranges["scale"] if self.ranges is not None else 1.0

    def t_re(self) -> np.ndarray:
        """The resolved t_Re as a (k,) float array (degrees)."""
        from .thresholds import t_re_array
        return t_re_array(self.thresholds, self.k)

    def flat_ranges(self):
        """``(rng, dead)`` broadcastable to the flat (k, n) arrays of a local normal
        mask: ``rng`` (k, 1) per image or (1, n) per pixel; ``dead`` (k, 1) bool for
        zero-range images (to be kept valid), or None when there is none."""
        if self._flat is None:
            rng = self.ranges["rng"]
            dead = self.ranges["dead"]
            self._flat = (rng.reshape(rng.shape[0], -1),
                          dead.reshape(-1, 1) if dead.any() else None)
        rng, dead = self._flat
        if self.pixels is not None and rng.shape[1] > 1:
            rng = rng[:, self.pixels]
        return rng, dead
