"""Experiment grids: load an experiment's YAML and expand it into run parameter dicts.

An experiment is found through the registry (``registry.get("experiments", name)``, see
:mod:`psbench.experiments`); its grid is the YAML file beside its module::

    experiment:
      name: table5_3
      description: "..."
      grids:              # union of cartesian products; keys are run parameters
        - {surface: [semisphere, spheres], lights: [45x8], mask: [None, Th], noise: [0.0, 0.1]}
      fixed: {model: ts, shadows: true}
      scales:
        full: {size: 512, seed: [0]}
        ci:   {size: 48, seed: [0]}

Values may use OmegaConf interpolations: resolvers such as ``${oc.env:VAR,default}`` and
``${results_dir}`` (the results store the runs go to). For each grid entry the
parameters are: base (the command line's run parameters) < ``fixed`` < the grid entry <
``scales[scale]``; then every list value expands
(cartesian product). Values that must stay lists (``extras``) are lists of lists in
the grid, or plain lists in ``fixed``/scale when given as ``[[...]]``. ``zenith`` and
``count`` build ``lights = "<zenith>x<count>"`` unless ``lights`` is set by the
experiment. Duplicate runs (same run_id) are kept once, in first-seen order.
"""
from __future__ import annotations

import itertools

from .. import registry
from .._shared.checks import PsbenchError
from .run import PARAMS, normalize, run_id

__all__ = ["expand", "experiment_spec", "load", "check_scale", "available"]

_LIST_PARAMS = ("extras",)   # list-valued parameters: a flat list is ONE value
_DICT_PARAMS = ("thresholds", "args")


def experiment_spec(exp) -> dict:
    """Validate the ``experiment`` mapping and return it as plain python."""
    from .run import _plain

    exp = _plain(exp)
    if isinstance(exp, str):
        return load(exp)
    if not isinstance(exp, dict):
        raise PsbenchError(f"experiment must be a mapping with name/grids, got {exp!r}")
    unknown = set(exp) - {"name", "description", "grids", "fixed", "scales"}
    if unknown:
        raise PsbenchError(f"experiment has unknown keys {sorted(unknown)}; valid: name, "
                           f"description, grids, fixed, scales")
    if not exp.get("name"):
        raise PsbenchError("experiment needs a name")
    grids = exp.get("grids") or [{}]
    if isinstance(grids, dict):
        grids = [grids]
    if not isinstance(grids, list) or not all(isinstance(g, dict) for g in grids):
        raise PsbenchError(f"experiment {exp['name']}: grids must be a list of mappings")
    exp["grids"] = grids
    exp["fixed"] = exp.get("fixed") or {}
    exp["scales"] = exp.get("scales") or {}
    return exp


def available() -> list[str]:
    """Names of the registered experiments."""
    return registry.names("experiments")


def load(name, *, results_dir=None) -> dict:
    """The validated grid of the registered experiment ``name``.

    Parameters
    ----------
    name : str
        A registered experiment (unknown names raise, listing the valid ones).
    results_dir : str or path-like, optional
        Value of ``${results_dir}`` in the YAML (default ``results``, relative to the
        current directory like the store's default).

    Returns
    -------
    dict
        The ``experiment`` mapping (see the module docstring), interpolations resolved.
    """
    from omegaconf import OmegaConf

    spec = registry.get("experiments", name, what="experiment")
    if spec.grid is None or not spec.grid.is_file():
        raise PsbenchError(f"experiment {spec.name!r} has no grid: expected a YAML file beside "
                           f"its module {getattr(spec.module, '__file__', spec.module)!r}")
    doc = OmegaConf.load(spec.grid)
    if "experiment" not in doc:
        raise PsbenchError(f"{spec.grid}: expected a top-level 'experiment:' mapping")
    ctx = OmegaConf.create({"results_dir": str(results_dir if results_dir is not None
                                               else "results")})
    ctx.experiment = doc.experiment
    try:
        exp = OmegaConf.to_container(ctx.experiment, resolve=True) or {}
    except Exception as exc:  # noqa: BLE001 - OmegaConf's errors name the key
        raise PsbenchError(f"{spec.grid}: cannot resolve the grid: {exc}") from None
    exp.setdefault("name", spec.name)
    if exp["name"] != spec.name:
        raise PsbenchError(f"{spec.grid}: name {exp['name']!r} differs from the registered "
                           f"experiment name {spec.name!r}")
    return experiment_spec(exp)


def check_scale(exp, scale) -> None:
    """Refuse a scale the experiment does not define (unless it defines none)."""
    scales = exp.get("scales") or {}
    if scales and scale not in scales:
        raise PsbenchError(f"experiment {exp['name']}: scale={scale!r} is not defined; valid "
                           f"choices: {', '.join(scales)}")


def _axis(key, value):
    """The list of values one key takes."""
    if key in _LIST_PARAMS:
        if isinstance(value, list) and value and all(isinstance(v, list) for v in value):
            return value
        return [value]
    if isinstance(value, list):
        if not value:
            raise PsbenchError(f"grid key {key!r} has an empty list of values")
        return value
    return [value]


def expand(exp, scale="full", base=None, *, base_dir=None) -> list[dict]:
    """Expand an experiment into normalized run parameter dicts.

    Parameters
    ----------
    exp : mapping or str
        The ``experiment`` config (see module docstring), or the name of a registered
        experiment (its grid is loaded with :func:`load`).
    scale : str
        Key of ``exp["scales"]`` (``full``, ``ci``, ...). A scale the experiment does
        not define is an error listing the defined ones (unless it defines none).
    base : dict, optional
        Defaults for parameters the experiment does not set (the command line's).

    Returns
    -------
    list of dict
        Normalized parameters (:func:`psbench.harness.run.normalize`), unique by run_id.
    """
    exp = experiment_spec(exp)
    check_scale(exp, scale)
    over = exp["scales"].get(scale) or {}
    base = dict(base or {})
    out, seen = [], set()
    valid = set(PARAMS) | {"zenith", "count"}
    for g in exp["grids"]:
        merged = {**exp["fixed"], **g, **over}
        bad = sorted(set(merged) - valid)
        if bad:
            raise PsbenchError(f"experiment {exp['name']}: unknown run parameter(s) {bad}; "
                               f"valid: {', '.join(sorted(valid))}")
        keys = list(merged)
        axes = [_axis(k, merged[k]) for k in keys]
        for combo in itertools.product(*axes):
            p = {k: v for k, v in base.items() if k in valid}
            if ("zenith" in keys or "count" in keys) and "lights" not in keys:
                p.pop("lights", None)
            p.update(zip(keys, combo))
            # lights: null in the grid (a data folder's own lights) wins over the base's
            # zenith/count
            if "zenith" in p and p.get("lights") is None and ("lights" not in keys
                                                              or "zenith" in keys):
                p.setdefault("count", 8)
            else:
                p.pop("zenith", None)
                p.pop("count", None)
            norm = normalize(p, base_dir=base_dir)
            rid = run_id(norm)
            if rid not in seen:
                seen.add(rid)
                out.append(norm)
    return out
