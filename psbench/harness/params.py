"""Run parameters: normalize, validate, identify (run id) and group (scene key).

Everything here is driven by the run spec (:mod:`psbench.harness.spec`): which keys
exist, their types, defaults, valid values, which run kinds use them and which of
them the rendered scene depends on.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError
from . import spec as S

__all__ = ["PARAMS", "normalize", "run_id", "scene_key", "validate", "plain"]

#: default run parameters (derived from the run spec)
PARAMS = S.defaults()
_SCENE = tuple(p.name for p in S.PARAMS if p.scene)
_UNLESS_DEFAULT = {p.name: p.default for p in S.PARAMS if p.hashed == "unless_default"}


def plain(value):
    """OmegaConf / numpy containers -> plain python."""
    try:
        from omegaconf import DictConfig, ListConfig, OmegaConf

        if isinstance(value, (DictConfig, ListConfig)):
            return OmegaConf.to_container(value, resolve=True)
    except ImportError:  # pragma: no cover
        pass
    if isinstance(value, np.generic):
        return value.item()
    return value


def _num(v):
    """45.0 -> '45', 37.5 -> '37.5' (for light specs)."""
    v = float(v)
    return str(int(v)) if v.is_integer() else repr(v)


def normalize(params: dict, *, base_dir=None) -> dict:
    """Complete and canonicalize run parameters (the run's identity).

    Unknown keys are refused (listing the valid ones). ``zenith``/``count`` are
    accepted and turned into ``lights = "<zenith>x<count>"`` when ``lights`` is not
    given. Paths (``data``, file ``surface``) become absolute (relative to
    ``base_dir`` or the CWD). Parameters that cannot affect the run are set to None
    (render options of a ``data`` run, everything but ``lights`` of a ``cond`` run),
    so they do not change the run id. Method ``options`` are checked by the method's
    options class; those equal to its defaults are dropped.
    """
    p = {k: plain(v) for k, v in dict(params).items()}
    zen, cnt = p.pop("zenith", None), p.pop("count", None)
    unknown = sorted(set(p) - set(PARAMS))
    if unknown:
        raise PsbenchError(f"unknown run parameter(s) {unknown}; valid: "
                           f"{', '.join(S.param_names(aliases=True))}")
    if p.get("lights") is None and zen is not None:
        p["lights"] = f"{_num(zen)}x{S.as_int(cnt if cnt is not None else 8, 'count')}"
    explicit = {k for k, v in p.items() if v is not None}
    raw = {k: p.get(k, v) for k, v in PARAMS.items()}
    raw = {k: (json.loads(json.dumps(v)) if isinstance(v, (dict, list)) else v)
           for k, v in raw.items()}
    ctx = dict(base=Path(base_dir) if base_dir is not None else Path.cwd(),
               data_run=raw["data"] is not None, explicit=explicit, out={})
    out = ctx["out"]
    out["kind"] = kind = S.SPEC["kind"].coerce(raw["kind"])
    S.check_kind(kind)
    for par in S.PARAMS:
        if par.alias or par.name == "kind":
            continue
        v = raw[par.name]
        if not S.uses(par, kind):
            v = par.empty
        elif ctx["data_run"] and par.synthetic:
            v = None
        elif par.normalize is not None:
            v = par.normalize(v, ctx)
        else:
            v = par.coerce(v)
        out[par.name] = v
    if kind == "cond" and out["lights"] is None:
        raise PsbenchError("kind=cond needs lights")
    if kind == "analysis" and not out["analysis"]:
        raise PsbenchError("kind=analysis needs analysis=<name of a registered analysis>")
    return out


#: what a path inside the results store is hashed as (:func:`run_id`)
STORE_TOKEN = "${results_dir}"


def run_id(params: dict, *, root=None) -> str:
    """Stable 16-hex-digit hash of normalized parameters.

    Parameters declared ``hashed="unless_default"`` enter the hash only when they differ
    from their default, so runs stored before they existed keep their ids.

    ``root`` is the results store the run belongs to: a path inside it (a surface file an
    experiment makes in its store, a capture folder under it) is hashed relative to it, so
    a store that is moved or copied keeps its run ids.

    The ``study`` keys an analysis declares operational
    (:attr:`psbench.registry.Analysis.operational`: a cache folder, a process count) are
    left out: they change how a run is computed, not what it computes.
    """
    p = dict(params)
    if isinstance(p.get("study"), dict) and p.get("analysis"):
        drop = _operational(p["analysis"])
        if drop:
            p["study"] = {k: v for k, v in p["study"].items() if k not in drop}
    p = {k: v for k, v in p.items() if not (k in _UNLESS_DEFAULT and v == _UNLESS_DEFAULT[k])}
    if root is not None:
        inside = str(Path(root).expanduser().resolve()) + os.sep
        p = {k: STORE_TOKEN + os.sep + v[len(inside):]
             if isinstance(v, str) and v.startswith(inside) else v for k, v in p.items()}
    blob = json.dumps(p, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def _operational(analysis) -> tuple:
    """``study`` keys the registered analysis declares operational (none if unknown)."""
    from .. import registry

    spec = registry.analyses().get(analysis)
    return tuple(getattr(spec, "operational", ()) or ())


def scene_key(params: dict) -> tuple:
    """Runs with equal keys share one rendered (or read) scene."""
    return tuple(json.dumps(params.get(k), sort_keys=True) for k in _SCENE)


def validate(params: dict) -> None:
    """Check names against their sources (registries, files) before any work.

    Raises
    ------
    PsbenchError
        One line naming the parameter and listing the valid choices.
    """
    kind = params["kind"]
    if kind not in S.RUN_KINDS:
        return                      # a plug-in kind checks its own parameters
    for par in S.PARAMS:
        v = params.get(par.name)
        if kind in par.checked and v is not None:
            par.validate(v, params)
