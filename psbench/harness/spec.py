"""The run spec: every run parameter and harness setting of ``psbench``, declared once.

Each entry of :data:`PARAMS` (run parameters: their values identify a run) and
:data:`SETTINGS` (how runs are executed and stored; never part of a run's identity) is
one :class:`Param`: name, type, default, valid values and a one-line help. Everything
else is derived from these two lists:

- the Hydra defaults: :func:`hydra_node` is stored in Hydra's ConfigStore as
  ``psbench_spec``, the first entry of the defaults list of ``psbench/conf/config.yaml``
  (which holds only Hydra's own settings);
- the store's parameter columns (:mod:`psbench.harness.schema`);
- normalization, validation, run ids and scene keys (:mod:`psbench.harness.params`);
- the choices printed by ``psbench --help`` (:mod:`psbench.harness.help`).

Valid values that come from plug-ins (masks, methods, surfaces, experiments) are read
from :mod:`psbench.registry` when needed, never copied here.

Adding a run parameter is one entry of :data:`PARAMS`, e.g.::

    Param("gamma", "float", 1.0, "display gamma applied to the rendered images",
          synthetic=True, scene=True, hashed="unless_default"),

``hashed="unless_default"`` keeps the ids of runs stored before the parameter existed:
the parameter enters the run id only when it differs from its default.
"""
from __future__ import annotations

import copy
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .._shared.checks import PsbenchError
from .._shared.deprecation import renamed_names
from . import choices as C

__all__ = ["Param", "PARAMS", "SETTINGS", "SPEC", "RUN_KINDS", "EXTRAS", "LAUNCHERS", "HYDRA_NODE",
           "uses", "check_kind", "plugin_kind",
           "param_names", "defaults", "hydra_node", "register_hydra", "columns", "column_value",
           "coerce_settings"]

#: name of the generated defaults node in Hydra's ConfigStore
HYDRA_NODE = "psbench_spec"
#: the built-in run kinds; plug-ins add others (:class:`psbench.registry.RunKind`)
RUN_KINDS = ("solve", "cond", "analysis")
EXTRAS = ("ne_by_zenith", "ne_map")
LAUNCHERS = ("joblib", "submitit_local", "submitit_slurm", "submitit_debug")
ALL_KINDS = RUN_KINDS
_SAME = object()
_TYPES = ("str", "int", "float", "bool", "mapping", "list")
_ARROW = {"str": "string", "int": "int64", "float": "float64", "bool": "bool",
          "mapping": "string", "list": "string"}


# ----------------------------------------------------------------------------- coercion
def as_bool(v, name):
    """true/false, 1/0 or "true"/"false" -> bool."""
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, str) and v.lower() in ("true", "false"):
        return v.lower() == "true"
    if isinstance(v, (int, np.integer)) and v in (0, 1):
        return bool(v)
    raise PsbenchError(f"{name} must be true or false, got {v!r}")


def as_int(v, name):
    """An integral number (5, 5.0, "5") -> int; bools refused."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be an integer, got {v!r}") from None
    if isinstance(v, bool) or not f.is_integer():
        raise PsbenchError(f"{name} must be an integer, got {v!r}")
    return int(f)


def as_float(v, name):
    """A finite number -> float; bools refused."""
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be a number, got {v!r}") from None
    if isinstance(v, bool) or not math.isfinite(f):
        raise PsbenchError(f"{name} must be a finite number, got {v!r}")
    return f


def _is_path(s) -> bool:
    s = str(s)
    return s.lower().endswith((".npy", ".png", ".x3p")) or "/" in s or os.sep in s


# ----------------------------------------------------------------------------- Param
@dataclass(frozen=True)
class Param:
    """One run parameter or harness setting.

    Attributes
    ----------
    name : str
        Key on the command line (``name=value``), in run parameter dicts and, for run
        parameters, the store column.
    type : {"str", "int", "float", "bool", "mapping", "list"}
        Value type; mappings and lists are stored as json text.
    default : object
        Default of :func:`psbench.harness.run.normalize` (and of Hydra unless ``hydra``).
    help : str
        One line for ``psbench --help``.
    choices : tuple or callable, optional
        Valid values: a tuple, or a callable returning ``{name: one-line help}`` read
        when needed (registries). Tuples are checked while normalizing, callables by
        :func:`psbench.harness.run.validate`.
    nullable : bool
        None (``null``) is a valid value.
    kinds : tuple of str
        Run kinds that use it; for the others it is reset to None (``{}``/``[]``),
        so it does not change their run id.
    checked : tuple of str
        Run kinds for which :func:`psbench.harness.run.validate` checks it.
    synthetic : bool
        Only meaningful for rendered scenes: None in ``data=`` runs.
    scene : bool
        The scene (rendered or read images) depends on it: runs equal in every scene
        parameter share one render.
    hashed : {"always", "unless_default"}
        "unless_default": the run id includes it only when it differs from its default
        (parameters added after runs were stored keep those runs' ids).
    alias : bool
        Input only (``zenith``/``count`` build ``lights``); its column is derived.
    normalize : callable, optional
        ``f(value, ctx) -> value`` replacing the plain type coercion (``ctx``:
        ``base`` folder, ``data_run``, ``explicit`` keys, ``out`` so far).
    check : callable, optional
        ``f(value, params)`` raising :class:`PsbenchError`; replaces the membership test.
    hydra : object
        Hydra default when it differs from ``default`` (an interpolation).
    metavar : str
        How ``--help`` shows the value when there are no choices.
    """

    name: str
    type: str
    default: Any
    help: str
    choices: tuple | Callable[[], dict] | None = None
    nullable: bool = False
    kinds: tuple = ALL_KINDS
    checked: tuple = ()
    synthetic: bool = False
    scene: bool = False
    hashed: str = "always"
    alias: bool = False
    normalize: Callable | None = None
    check: Callable | None = None
    hydra: Any = _SAME
    metavar: str = ""

    def __post_init__(self):
        if self.type not in _TYPES:
            raise PsbenchError(f"Param {self.name!r}: type must be one of {_TYPES}, got {self.type!r}")
        if self.hashed not in ("always", "unless_default"):
            raise PsbenchError(f"Param {self.name!r}: hashed must be 'always' or 'unless_default'")

    @property
    def empty(self):
        """The value of a parameter its run kind does not use."""
        return {} if self.type == "mapping" else [] if self.type == "list" else None

    @property
    def hydra_default(self):
        return copy.deepcopy(self.default if self.hydra is _SAME else self.hydra)

    def names(self) -> dict:
        """Valid values, ``{value: help}`` (empty when any value of the type is valid)."""
        if self.choices is None:
            return {}
        if callable(self.choices):
            return dict(self.choices())
        return {str(c): "" for c in self.choices}

    def coerce(self, value):
        """Plain type coercion (choices of a tuple checked)."""
        if value is None and self.nullable:
            return None
        t = self.type
        if t == "str":
            value = str(value)
        elif t == "int":
            value = as_int(value, self.name)
        elif t == "float":
            value = as_float(value, self.name)
        elif t == "bool":
            value = as_bool(value, self.name)
        elif t == "mapping":
            value = value or {}
            if not isinstance(value, dict):
                raise PsbenchError(f"{self.name} must be a mapping, got {value!r}")
            return {str(a): value[a] for a in sorted(value)}
        else:
            value = value or []
            value = [value] if isinstance(value, str) else list(value)
            if isinstance(self.choices, tuple):
                for e in value:
                    if e not in self.choices:
                        raise PsbenchError(f"{self.name} entry {e!r} is not known; valid "
                                           f"choices: {', '.join(self.choices)}")
            return sorted(set(value))
        if isinstance(self.choices, tuple) and value not in self.choices:
            raise PsbenchError(f"{self.name}={value!r} is not known; valid choices: "
                               f"{', '.join(self.choices)}")
        return value

    def validate(self, value, params):
        """Check a normalized value (choices from a callable / ``check``)."""
        if self.check is not None:
            self.check(value, params)
        elif callable(self.choices):
            valid = self.names()
            if valid and value not in valid:
                raise PsbenchError(f"{self.name}={value!r} is not known; valid choices: "
                                   f"{', '.join(valid)}")


# ----------------------------------------------------------------------------- hooks
def _surface(value, ctx):
    s = str(value)
    return str((ctx["base"] / Path(s).expanduser()).resolve()) if _is_path(s) else s


def _data(value, ctx):
    return None if value is None else str((ctx["base"] / Path(str(value)).expanduser()).resolve())


def _lights(value, ctx):
    if ctx["data_run"] and "lights" not in ctx["explicit"]:
        return None          # a data folder uses all its lights; a layout selects the nearest
    return str(value).replace(" ", "")


def _shadows(value, ctx):
    if isinstance(value, str) and value.lower() in ("all", "self", "none"):
        value = {"all": True, "self": False, "none": "none"}[value.lower()]
    return value if value == "none" else as_bool(value, "shadows")


def _size(value, ctx):
    return None if _is_path(ctx["out"]["surface"]) else as_int(value, "size")


def _bounces(value, ctx):
    """0 is stored as None (the default): the ids of runs stored before ``bounces``
    existed, and of the kinds and data runs that do not render, stay unchanged."""
    v = None if value is None else as_int(value, "bounces")
    if v not in (None, 0, 1, 2):
        raise PsbenchError(f"bounces must be 0, 1 or 2, got {value!r}")
    return v or None


#: the render options a run may set through ``render`` (the others are run parameters)
RENDER_OPTIONS = ("rho_d", "rho_s", "m", "phong_m", "roughness", "f0", "albedo_texture",
                  "second_material", "light_error", "power_error", "light_distance", "falloff",
                  "ambient", "saturation", "gamma")


def _render(value, ctx):
    """Render options: known names, values checked as render checks them."""
    value = value or {}
    if not isinstance(value, dict):
        raise PsbenchError(f"render must be a mapping of render options, got {value!r}")
    value = {str(a): value[a] for a in sorted(value)}
    bad = sorted(set(value) - set(RENDER_OPTIONS))
    if bad:
        raise PsbenchError(f"render: unknown option(s) {bad}; valid: {', '.join(RENDER_OPTIONS)}")
    from ..render import _departures

    dep = {k: value.get(k, d) for k, d in (
        ("albedo_texture", 0.0), ("second_material", None), ("light_error", 0.0),
        ("power_error", 0.0), ("light_distance", None), ("ambient", 0.0),
        ("saturation", None), ("gamma", 1.0))}
    try:
        _departures.check(**dep)
        for k in ("rho_d", "rho_s", "m", "phong_m", "roughness", "f0"):
            if k in value:
                as_float(value[k], k)
        if "falloff" in value:
            value["falloff"] = as_bool(value["falloff"], "falloff")
    except PsbenchError as exc:
        raise PsbenchError(f"render: {exc}") from None
    return value


def _options(value, ctx):
    """Method options: a mapping checked by the method's options class; values equal
    to the class's defaults are dropped (``options.max_iter=10`` is the default run)."""
    value = value or {}
    if not isinstance(value, dict):
        raise PsbenchError(f"options must be a mapping of option names to values, got {value!r}")
    value = {str(a): value[a] for a in sorted(value)}
    if not value or ctx["out"]["kind"] != "solve":
        return value
    clash = sorted(set(value) & set(SPEC))
    if clash:
        raise PsbenchError(f"options.{clash[0]} is a run parameter: set {clash[0]}=... instead")
    method = ctx["out"]["method"]
    cls = C.options_class(method)
    try:
        cls.build(value, method=method)
    except PsbenchError as exc:
        raise PsbenchError(f"options: {exc}") from None
    default = cls()                 # a value equal to the default is the default run
    from ..solve.base import RENAMED_OPTIONS

    value = {RENAMED_OPTIONS.get(k, k): v for k, v in value.items()}    # build() warned
    return {k: v for k, v in sorted(value.items()) if v != getattr(default, k)}


# ----------------------------------------------------------------------------- the spec
_RUN = ("solve", "analysis")      # kinds that render / read a scene
_SCENE = ("solve", "analysis")

#: Run parameters, in column order. Together they identify a run (run id).
PARAMS: tuple[Param, ...] = (
    Param("kind", "str", "solve", "what the run computes", choices=C.run_kinds, scene=True),
    Param("surface", "str", "sombrero2", "test surface: a name, or a path to a .npy / 16-bit "
          ".png height map (pixel units) or an .x3p topography (um, its pixel size)", choices=C.surfaces, kinds=_RUN, checked=_SCENE,
          synthetic=True, scene=True, normalize=_surface, check=C.check_surface),
    Param("data", "str", None, "a folder in the DiLiGenT layout, read instead of rendering",
          nullable=True, kinds=_RUN, checked=_SCENE, scene=True, normalize=_data,
          check=C.check_data, metavar="FOLDER"),
    Param("lights", "str", "45x8", "light layout: rings ZENITHxCOUNT joined by '+' (30x8+60x8); "
          "with data=, the folder's nearest lights", checked=RUN_KINDS, scene=True,
          normalize=_lights, check=C.check_lights, hydra="${zenith}x${count}", metavar="LAYOUT"),
    Param("zenith", "float", 45, "source zenith of the default single ring, degrees "
          "(lights=<zenith>x<count>)", alias=True, metavar="DEG"),
    Param("count", "int", 8, "sources in that ring", alias=True, metavar="N"),
    Param("model", "str", "ts", "reflectance model of the renderer", choices=C.models, kinds=_RUN,
          checked=_SCENE, synthetic=True, scene=True),
    Param("shadows", "bool", True, "true: cast and self shadows; self: self shadows only; "
          "none: no shadows", kinds=_RUN, synthetic=True,
          scene=True, normalize=_shadows),
    Param("noise", "float", 0.05, "Gaussian noise, sigma as a fraction of each image's "
          "dynamic range", kinds=_RUN, synthetic=True, scene=True, metavar="FRACTION"),
    Param("quantize", "int", None, "quantize the images to this many bits (null: float)",
          nullable=True, kinds=_RUN, synthetic=True, scene=True, metavar="BITS"),
    Param("bounces", "int", None, "interreflection bounces rendered (null or 0: direct light "
          "only; 1 or 2: secondary light, ground truth secondary_fraction)", nullable=True,
          kinds=_RUN, synthetic=True, scene=True, hashed="unless_default", normalize=_bounces,
          metavar="0|1|2"),
    Param("render", "mapping", {}, "more render options (psbench.render): material "
          "(rho_d, rho_s, m, roughness, f0, phong_m) and departures from the solvers' model "
          "(albedo_texture, second_material, light_error, power_error, light_distance, "
          "falloff, ambient, saturation, gamma): render.gamma=2.2", kinds=_RUN,
          synthetic=True, scene=True, hashed="unless_default", normalize=_render,
          metavar="{}"),
    Param("size", "int", 512, "image side in pixels (named surfaces)", kinds=_RUN,
          synthetic=True, scene=True, normalize=_size, metavar="PIXELS"),
    Param("mask", "str", "Th", "mask expression: mask names joined by '-' (Th-Hi-Re-Sh); None: "
          "plain least squares", choices=C.masks, kinds=_RUN, checked=("solve",),
          check=C.check_mask, metavar="EXPR"),
    Param("weighted", "bool", False, "weighted masks (Section 3.4.2) after the binary solve",
          kinds=_RUN),
    Param("method", "str", "ps", "estimator of rho n per pixel", choices=C.methods, kinds=_RUN,
          checked=("solve",)),
    Param("weight", "str", None, "WPS ring weight (method=wps; null: the method's default)",
          choices=C.wps_weights, nullable=True, kinds=_RUN, checked=("solve",)),
    Param("binary", "bool", False, "WPS: all weight on the ring with the largest weight "
          "(Eq. 4.12)", kinds=_RUN),
    Param("options", "mapping", {}, "options of the method: options.NAME=VALUE, checked by "
          "the method's options class (listed below)", kinds=_RUN, hashed="unless_default",
          normalize=_options, metavar="{}"),
    Param("thresholds", "mapping", {}, "overrides of the Table 5.2 thresholds: "
          "thresholds.k_low=0.1", kinds=_RUN, metavar="{}"),
    Param("th_scope", "str", "image", "where Th / Hi / CS measure dynamic ranges (image: the "
          "thesis's rule)", choices=C.th_scopes, kinds=_RUN, checked=("solve",)),
    Param("seed", "int", 0, "seed of the noise and of random subsets", kinds=_RUN, scene=True),
    Param("analysis", "str", None, "kind=analysis: a registered analysis (psbench.analysis or a plug-in)",
          choices=C.analyses, nullable=True, kinds=("analysis",), checked=("analysis",),
          check=C.check_analysis, metavar="NAME"),
    Param("args", "mapping", {}, "kind=analysis (and plug-in kinds): extra keyword arguments", kinds=_RUN,
          metavar="{}"),
    Param("study", "mapping", {}, "kind=analysis: settings an experiment's scale gives its "
          "analysis (chapter7: guns, cases, time_size, ...)", kinds=("analysis",),
          hashed="unless_default", metavar="{}"),
    Param("extras", "list", [], "extra outputs stored with the row", choices=EXTRAS, kinds=_RUN),
)

_SUBMITIT = dict(folder=None, wait=True, timeout_min=240, cpus_per_task=None, mem_gb=None,
                 slurm_partition=None, slurm_additional_parameters=None)

#: Harness settings: how runs are executed and stored (not part of a run's identity).
SETTINGS: tuple[Param, ...] = (
    Param("results_dir", "str", "results", "results store, relative to the current folder "
          "($PSBENCH_RESULTS)", hydra="${oc.env:PSBENCH_RESULTS,results}", metavar="DIR"),
    Param("sweep", "str", "adhoc", "store folder of command-line runs: "
          "<results_dir>/runs/<sweep>/", metavar="NAME"),
    Param("out", "str", None, "folder for the run's pictures; in a -m sweep one folder per "
          "run in it and the comparison sheet (default <results_dir>/out/<sweep>/[<run_id>])",
          nullable=True, metavar="DIR"),
    Param("outputs", "str", "pictures", "what a run writes to out: pictures (PNGs: input, "
          "normals, truth, NE map, albedo, mask, weights, shaded heights), all (pictures, "
          ".npy arrays, PLY and OBJ height meshes), none", choices=("pictures", "all", "none")),
    Param("rerun", "bool", False, "redo runs that are already stored"),
    Param("retry_failed", "bool", False, "redo stored runs whose status is failed (sweeps, "
          "experiments)"),
    Param("experiment", "str", None, "set by +experiment=NAME: a thesis experiment's grid",
          choices=C.experiments, nullable=True, metavar="NAME"),
    Param("scale", "str", "full", "experiment scale (full, ci, or as the experiment defines)",
          metavar="SCALE"),
    Param("jobs", "int", -1, "experiment: joblib workers (-1: all cores); per shard job with "
          "submitit_slurm", metavar="N"),
    Param("launcher", "str", "joblib", "experiment: how chunks run", choices=LAUNCHERS),
    Param("shards", "int", 1, "experiment: shard jobs for the submitit launchers", metavar="N"),
    Param("submitit", "mapping", _SUBMITIT, "experiment: submitit executor parameters "
          "(submitit.slurm_partition=P, ...)", metavar="{...}"),
)

#: name -> Param of every run parameter (aliases included)
SPEC: dict[str, Param] = {p.name: p for p in PARAMS}
_SETTINGS = {p.name: p for p in SETTINGS}


def plugin_kind(kind):
    """The :class:`~psbench.registry.RunKind` of a plug-in kind."""
    from .. import registry

    return registry.get("run_kinds", kind, what="kind")


def check_kind(kind) -> None:
    """Raise unless ``kind`` is a built-in or registered run kind (listing them)."""
    if kind not in RUN_KINDS and kind not in C.run_kinds():
        raise PsbenchError(f"kind={kind!r} is not known; valid choices: "
                           f"{', '.join(C.run_kinds())}")


def uses(par, kind) -> bool:
    """Whether a run of ``kind`` reads parameter ``par`` (a plug-in kind: the parameters
    its :class:`~psbench.registry.RunKind` names, by default those of a ``solve`` run)."""
    if kind in RUN_KINDS:
        return kind in par.kinds
    names = plugin_kind(kind).params
    return "solve" in par.kinds if names is None else par.name in names


def param_names(*, aliases=False) -> tuple[str, ...]:
    """Names of the run parameters (with ``zenith``/``count`` when ``aliases``)."""
    return tuple(p.name for p in PARAMS if aliases or not p.alias)


def defaults() -> dict:
    """Default run parameters (aliases excluded)."""
    return {p.name: copy.deepcopy(p.default) for p in PARAMS if not p.alias}


def hydra_node() -> dict:
    """The Hydra defaults of every run parameter and harness setting."""
    return {p.name: p.hydra_default for p in PARAMS + SETTINGS}


def register_hydra() -> None:
    """Store :func:`hydra_node` in Hydra's ConfigStore as :data:`HYDRA_NODE` (idempotent)."""
    from hydra.core.config_store import ConfigStore

    ConfigStore.instance().store(name=HYDRA_NODE, node=hydra_node())


def columns() -> list[tuple[str, str]]:
    """``(name, arrow type alias)`` of the parameter columns of the store."""
    return [(p.name, _ARROW[p.type]) for p in PARAMS]


def column_value(name, value):
    """A normalized parameter as stored: mappings / lists as json (null when empty),
    ``shadows="none"`` as False (the exact value is in ``config``)."""
    import json

    p = SPEC[name]
    if p.type == "mapping":
        return json.dumps(value, sort_keys=True) if value else None
    if p.type == "list":
        return json.dumps(value) if value else None
    if name == "shadows" and value == "none":
        return False
    return value


def coerce_settings(values: dict) -> dict:
    """Harness settings coerced to their types (one-line error naming the setting)."""
    out = {}
    for name, v in values.items():
        p = _SETTINGS.get(name)
        skip = p is None or p.type == "mapping" or name == "experiment"   # a grid mapping
        out[name] = v if skip else p.coerce(v)
    return out


__getattr__ = renamed_names(globals(), {"KINDS": "RUN_KINDS"})
