"""Plug-in registries: masks, methods, experiments, surfaces, analyses, forensic recipes
and run kinds.

psbench grows by adding modules, not by editing lists. Each piece is a small frozen
spec object (:class:`Mask`, :class:`Method`, :class:`Experiment`, :class:`SurfaceSpec`,
:class:`Analysis`, :class:`Recipe`, :class:`RunKind`) published through a Python
entry-point group:

===================  =========================  ==============================================
group                entry-point value          loaded object
===================  =========================  ==============================================
psbench.masks        ``pkg.module:MASK``        :class:`Mask`
psbench.methods      ``pkg.module:METHOD``      :class:`Method`
psbench.experiments  ``pkg.module``             a module (wrapped in :class:`Experiment`)
psbench.surfaces     ``pkg.module:SURFACE``     :class:`SurfaceSpec`
psbench.analyses     ``pkg.module:function``    a function (wrapped in :class:`Analysis`)
                     or ``pkg.module:SPEC``     or an :class:`Analysis`
psbench.recipes      ``pkg.module:RECIPE``      :class:`Recipe` (a forensic study method)
psbench.run_kinds    ``pkg.module:RUN_KIND``    :class:`RunKind` (a ``kind=`` of the harness)
===================  =========================  ==============================================

A built-in module may define a tuple of specs under the attribute (``ANALYSES`` in
:mod:`psbench.analysis.builtin`, ``RECIPES`` in :mod:`psbench.forensic.pipeline`).

psbench's own pieces are declared in its ``pyproject.toml`` under the same groups, so a
third-party package extends psbench exactly as psbench extends itself (as pytest and
benchopt do). When psbench runs from a source tree without installed metadata, its
built-ins are found by convention as well (every public module of the built-in packages
that defines the attribute), so a new built-in is one new module. :func:`register` adds a piece at run time (notebooks, tests).

This module is the bottom layer: it imports nothing of psbench but the error type and
never imports a plug-in before it is asked for.
"""
from __future__ import annotations

import importlib
import pkgutil
import types
import warnings
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any, Callable

from ._shared.checks import PsbenchError

__all__ = ["Threshold", "Mask", "Method", "Experiment", "SurfaceSpec", "Analysis", "Recipe",
           "RunKind", "GROUPS", "masks", "methods", "experiments", "surfaces", "analyses",
           "recipes", "run_kinds", "get", "names", "register", "unregister", "reload"]


# ----------------------------------------------------------------------------- specs
@dataclass(frozen=True)
class Threshold:
    """A threshold a mask reads.

    Attributes
    ----------
    name : str
        Key in ``solve(..., thresholds={name: value})`` and ``+thresholds.<name>=``.
    default : float, tuple of float, or callable
        A number; a tuple of values per image count in ``counts`` (linearly
        interpolated in k between them and clamped outside, as Table 5.2 is read); or
        ``f(k, lights) -> float | tuple`` for rules such as Eq. 5.1.
    range : (float, float)
        Inclusive valid range; values outside it are refused before any work.
    counts : tuple of int, optional
        Image counts of the columns of a tuple ``default``.
    per_light : bool
        The value may be a sequence of k numbers, one per light.
    help : str
        One line for ``--help`` and the docs.
    """

    name: str
    default: Any
    range: tuple[float, float]
    counts: tuple[int, ...] | None = None
    per_light: bool = False
    help: str = ""


@dataclass(frozen=True)
class Mask:
    """A mask of the unified framework (Fig. 3.1).

    Attributes
    ----------
    name : str
        Token in mask expressions (``"Th"`` in ``"Th-Hi-Re-Sh"``); case-insensitive.
    stage : {"image", "subset", "normal"}
        Where it acts in Fig. 3.1: on the images before PS, as a subset method, or
        from the current normals inside the PS <-> normal-mask loop.
    func : callable
        The mask itself; its signature is fixed by the stage (see
        :mod:`psbench.solve` for the contracts).
    images : (int, int or None)
        Accepted image counts, inclusive (``(4, 4)``: exactly four; ``None``: no
        upper limit).
    thresholds : tuple of Threshold
        Thresholds it reads (resolved per image count, validated against ``range``).
    ranges : bool
        It reads the images' dynamic ranges (Th, Hi, CS, NL).
    local : bool
        Normal stage only: depends on each pixel's own solution alone, so the loop
        re-evaluates it only where the solution changed (False for Sh, which
        integrates the whole surface).
    fuses : bool
        Subset stage only: returns its own fused solution (CJ) and cannot be combined
        with other masks.
    help : str
        One line for ``--help`` and the docs.
    """

    name: str
    stage: str
    func: Callable
    images: tuple[int, int | None] = (3, None)
    thresholds: tuple[Threshold, ...] = ()
    ranges: bool = False
    local: bool = True
    fuses: bool = False
    help: str = ""

    def __post_init__(self):
        if self.stage not in ("image", "subset", "normal"):
            raise PsbenchError(f"Mask {self.name!r}: stage must be 'image', 'subset' or "
                               f"'normal', got {self.stage!r}")
        if not self.name or not self.name.isidentifier() or self.name.lower() == "none":
            raise PsbenchError(f"Mask name {self.name!r} must be an identifier other than None")


@dataclass(frozen=True)
class Method:
    """An estimator of rho * n per pixel.

    Attributes
    ----------
    name : str
        ``solve(..., method=name)`` and ``psbench method=name``.
    func : callable
        ``func(problem, options) -> Fit`` (see :mod:`psbench.solve`).
    options : type
        A dataclass of the method's options: defaults, validation in
        ``__post_init__`` (raising :class:`psbench.PsbenchError`) and a numpydoc
        docstring documenting every field. Settable as ``options.<field>=`` on the
        command line and as keyword arguments of :func:`psbench.solve`.
    masked : bool
        True: the mask expression runs first and the method sees only the observations
        it keeps. False: the method runs the masks itself (WPS, once per ring).
    help : str
        One line for ``--help`` and the docs.
    """

    name: str
    func: Callable
    options: type
    masked: bool = True
    help: str = ""


@dataclass(frozen=True)
class SurfaceSpec:
    """A named test surface: ``func(size, **kw) -> Surface``.

    ``min_size`` is the smallest ``size`` its generator accepts with its default options
    (16 for most; a cartridge case needs enough pixels for its marks): the command line's
    dry runs build their miniature scenes at it.
    """

    name: str
    func: Callable
    help: str = ""
    aliases: tuple[str, ...] = ()
    min_size: int = 16


@dataclass(frozen=True)
class Experiment:
    """An experiment: its grid (YAML beside its module) and its module.

    The module defines (see :mod:`psbench.experiments`): ``TITLE``, ``AVERAGES``,
    ``NOTES`` (deviations from the thesis), ``THESIS`` (the thesis's values),
    ``aggregate(rows)``, ``verdicts(agg, rows)``, ``figures(agg)`` and ``GATED``.
    """

    name: str
    module: types.ModuleType
    grid: Path | None = None

    def __getattr__(self, item):  # TITLE, aggregate, ... straight from the module
        try:
            return getattr(object.__getattribute__(self, "module"), item)
        except AttributeError:
            raise AttributeError(f"experiment {self.name!r} has no {item!r}") from None


@dataclass(frozen=True)
class Analysis:
    """A ``kind=analysis`` computation: ``func(**kwargs)`` returning something JSON-able
    (a DataFrame, dict, list or number), stored as the row's ``payload``.

    The harness passes the run parameters ``func``'s signature names (``surface``,
    ``lights``, ``seed``, ...; ``zeniths=[zenith]`` for a plural name) plus the run's
    ``args``.

    ``operational`` names keys of the run's ``study`` mapping that choose how the result
    is computed, not what it is (a cache folder, a table of earlier results, a process
    count): they are left out of the run's id (:func:`psbench.harness.params.run_id`), so
    moving a cache leaves the stored runs current.
    """

    name: str
    func: Callable
    help: str = ""
    operational: tuple = ()


@dataclass(frozen=True)
class Recipe:
    """A PS method of the forensic identification study (Chapter 7): a label and the
    keyword arguments of :func:`psbench.solve` it stands for.

    Attributes
    ----------
    name : str
        The study's method label (``"Th-Hi-Re-Sh"``, ``"WPS"``, ...).
    solve : dict
        Keyword arguments of :func:`psbench.solve`; ``weights_um: True`` converts the
        weighted masks' pixel lengths to the case's pixel size
        (:func:`psbench.forensic.pipeline.solve_kwargs`).
    help : str
    """

    name: str
    solve: dict
    help: str = ""


@dataclass(frozen=True)
class RunKind:
    """A ``kind=`` of the harness besides ``solve``, ``cond`` and ``analysis``.

    Attributes
    ----------
    name : str
    func : callable
        ``func(params, row)``: computes the run from its normalized parameters and
        fills ``row``'s metric columns (an exception fails the run).
    params : tuple of str, optional
        The run parameters it reads (the others are left empty and out of its run id).
        None: those of a ``solve`` run.
    help : str
    """

    name: str
    func: Callable
    params: tuple[str, ...] | None = None
    help: str = ""

    def __post_init__(self):
        if self.name in ("solve", "cond", "analysis"):
            raise PsbenchError(f"RunKind {self.name!r}: a built-in kind cannot be replaced")


# ----------------------------------------------------------------------------- groups
#: group key -> (entry-point group, attribute that holds the spec, built-in packages or
#: modules: an upper layer's piece is named here, not imported by the lower layer)
GROUPS = {
    "masks": ("psbench.masks", "MASK", ("psbench.solve.masks",)),
    "methods": ("psbench.methods", "METHOD", ("psbench.solve.methods",)),
    "experiments": ("psbench.experiments", None, ("psbench.experiments",)),
    "surfaces": ("psbench.surfaces", "SURFACE", ("psbench.surfaces", "psbench.forensic.surface")),
    "analyses": ("psbench.analyses", "ANALYSES", ("psbench.analysis.builtin",)),
    "recipes": ("psbench.recipes", "RECIPES", ("psbench.forensic.pipeline",)),
    "run_kinds": ("psbench.run_kinds", "RUN_KIND", ()),
}
_TYPES = {"masks": Mask, "methods": Method, "experiments": Experiment, "surfaces": SurfaceSpec,
          "analyses": Analysis, "recipes": Recipe, "run_kinds": RunKind}

_loaded: dict[str, dict[str, Any]] = {}
_runtime: dict[str, dict[str, Any]] = {g: {} for g in GROUPS}
_removed: dict[str, set] = {g: set() for g in GROUPS}


def _wrap(group, name, obj):
    """Entry-point object -> spec (experiments are modules)."""
    if group == "experiments":
        if isinstance(obj, Experiment):
            return obj
        if not isinstance(obj, types.ModuleType):
            raise PsbenchError(f"experiment entry point {name!r} must name a module, got {obj!r}")
        grid = Path(obj.__file__).with_suffix(".yaml") if getattr(obj, "__file__", None) else None
        return Experiment(name=getattr(obj, "NAME", name), module=obj,
                          grid=grid if grid is not None and grid.is_file() else None)
    if group == "analyses" and callable(obj) and not isinstance(obj, Analysis):
        return Analysis(name=name, func=obj,
                        help=(obj.__doc__ or "").strip().split("\n")[0])
    if not isinstance(obj, _TYPES[group]):
        raise PsbenchError(f"{GROUPS[group][0]} entry point {name!r} must be a "
                           f"{_TYPES[group].__name__}, got {type(obj).__name__}")
    return obj


def _specs(group, name, obj):
    """The specs an entry point or a built-in module's attribute holds: one spec, a tuple
    of them, or (recipes) a dict label -> keyword arguments of :func:`psbench.solve`."""
    if group == "recipes" and isinstance(obj, dict):
        return [Recipe(label, dict(kw)) for label, kw in obj.items()]
    if isinstance(obj, (tuple, list)):
        return [_wrap(group, name, one) for one in obj]
    return [_wrap(group, name, obj)]


def _public_modules(pkg):
    """The public modules of a package, and of its public subpackages (a family of
    several modules, e.g. ``solve/methods/robust/``), depth first; a module: itself."""
    if not hasattr(pkg, "__path__"):
        yield pkg
        return
    for info in pkgutil.iter_modules(getattr(pkg, "__path__", []), pkg.__name__ + "."):
        if info.name.rsplit(".", 1)[-1].startswith("_"):
            continue
        mod = importlib.import_module(info.name)
        yield mod
        if info.ispkg:
            yield from _public_modules(mod)


def _builtin(group):
    """Built-ins by convention (a source tree without installed metadata)."""
    _, attr, packages = GROUPS[group]
    found = {}
    for pkg_name in packages:
        try:
            pkg = importlib.import_module(pkg_name)
        except ImportError:
            continue
        for mod in _public_modules(pkg):
            obj = mod if attr is None else getattr(mod, attr, None)
            if obj is None or (attr is None and not hasattr(mod, "aggregate")):
                continue
            for spec in _specs(group, mod.__name__.rsplit(".", 1)[-1], obj):
                found[spec.name] = spec
    return found


def _load(group):
    ep_group = GROUPS[group][0]
    specs = {}
    for ep in metadata.entry_points(group=ep_group):
        try:
            found = _specs(group, ep.name, ep.load())
        except Exception as exc:  # noqa: BLE001 - one broken plug-in must not break psbench
            warnings.warn(f"psbench: skipping {ep_group} entry point {ep.name!r} "
                          f"({ep.value}): {type(exc).__name__}: {exc}", RuntimeWarning,
                          stacklevel=3)
            continue
        for spec in found:
            if spec.name in specs and specs[spec.name] != spec:
                warnings.warn(f"psbench: {ep_group} name {spec.name!r} is registered twice; "
                              f"keeping the first", RuntimeWarning, stacklevel=3)
                continue
            specs[spec.name] = spec
    # built-in modules are also found by convention: a source tree without installed
    # metadata works, and a new built-in module is one file (its entry-point line in
    # pyproject.toml declares it to other tools but is not needed to find it)
    for name, spec in _builtin(group).items():
        specs.setdefault(name, spec)
    return specs


def _all(group) -> dict:
    if group not in GROUPS:
        raise PsbenchError(f"registry group {group!r} is not known; valid: {', '.join(GROUPS)}")
    if group not in _loaded:
        _loaded[group] = _load(group)
    out = {n: s for n, s in _loaded[group].items() if n not in _removed[group]}
    out.update(_runtime[group])
    return out


def masks() -> dict[str, Mask]:
    """Every registered mask, name -> :class:`Mask`."""
    return _all("masks")


def methods() -> dict[str, Method]:
    """Every registered method, name -> :class:`Method`."""
    return _all("methods")


def experiments() -> dict[str, Experiment]:
    """Every registered experiment, name -> :class:`Experiment`."""
    return _all("experiments")


def surfaces() -> dict[str, SurfaceSpec]:
    """Every registered surface, name -> :class:`SurfaceSpec` (aliases included)."""
    out = {}
    for name, spec in _all("surfaces").items():
        out[name] = spec
        for a in spec.aliases:
            out.setdefault(a, spec)
    return out


def analyses() -> dict[str, Analysis]:
    """Every registered ``kind=analysis`` computation, name -> :class:`Analysis`."""
    return _all("analyses")


def recipes() -> dict[str, Recipe]:
    """Every registered forensic study method, label -> :class:`Recipe`."""
    return _all("recipes")


def run_kinds() -> dict[str, RunKind]:
    """Every registered harness run kind besides the built-ins, name -> :class:`RunKind`."""
    return _all("run_kinds")


def names(group) -> list[str]:
    """Registered names of a group, sorted case-insensitively."""
    return sorted(_all(group) if group != "surfaces" else surfaces(), key=str.lower)


def get(group, name, *, what=None):
    """The spec ``name`` of ``group``; an unknown name raises, listing the valid ones.

    ``what`` names the argument in the message (default: the group's singular).
    """
    specs = _all(group) if group != "surfaces" else surfaces()
    if name in specs:
        return specs[name]
    low = {n.lower(): n for n in specs}
    if isinstance(name, str) and name.lower() in low:
        return specs[low[name.lower()]]
    arg = what or group[:-1]
    raise PsbenchError(f"{arg}={name!r} is not known; valid choices: "
                       f"{', '.join(names(group))}")


def register(group, spec, *, replace=False):
    """Register ``spec`` in ``group`` for this process (a module for experiments).

    Raises if the name is taken, unless ``replace``.
    """
    spec = _wrap(group, getattr(spec, "name", getattr(spec, "NAME", None)) or
                 getattr(spec, "__name__", "").rsplit(".", 1)[-1], spec)
    if not replace and spec.name in _all(group):
        raise PsbenchError(f"{group[:-1]} {spec.name!r} is already registered")
    _runtime[group][spec.name] = spec
    _removed[group].discard(spec.name)
    return spec


def unregister(group, name):
    """Remove a piece registered with :func:`register` (or hide an installed one)."""
    _runtime[group].pop(name, None)
    if name in _loaded.get(group, {}):
        _removed[group].add(name)


def reload(group=None):
    """Forget what was loaded (re-reads entry points on next use), e.g. after
    installing a plug-in into the running interpreter."""
    for g in ([group] if group else list(GROUPS)):
        _loaded.pop(g, None)
