"""Where the valid values of run parameters come from, read when needed.

Plug-in names (masks, methods, surfaces, experiments, analyses, run kinds) come from
:mod:`psbench.registry` (built-ins are always found there); fixed vocabularies (render
models, WPS weights, Th scopes) from the module that defines them, imported on first use.
Each source returns ``{name: one-line help}``; the ``check_*`` functions validate one
normalized value.
"""
from __future__ import annotations

import importlib
import os
from pathlib import Path

from .._shared.checks import PsbenchError

__all__ = ["masks", "methods", "surfaces", "experiments", "models", "wps_weights",
           "th_scopes", "run_kinds", "analyses", "choice_sources", "options_class", "check_surface", "check_data",
           "check_lights", "check_mask", "check_analysis"]


def _legacy(ref):
    """``module:attribute``, imported when first needed (keeps ``--help`` light); None
    when it no longer exists (``--help`` then says none are listed)."""
    mod, attr = ref.split(":")
    try:
        return getattr(importlib.import_module(mod), attr)
    except (ImportError, AttributeError):
        return None


def _registry(group) -> dict:
    """``{name: help}`` of a registry group."""
    from .. import registry

    specs = getattr(registry, group)()
    return {name: getattr(specs[name], "help", "") or (
        getattr(specs[name], "TITLE", "") if group == "experiments" else "")
        for name in sorted(specs, key=str.lower)}


def masks() -> dict:
    """Mask names (``None``, plain least squares, is always valid and not listed)."""
    return {n: h for n, h in _registry("masks").items()
            if n.lower() != "none"}


def methods() -> dict:
    return _registry("methods")


def surfaces() -> dict:
    return _registry("surfaces")


def experiments() -> dict:
    return _registry("experiments")


def models() -> dict:
    return {m: "" for m in (_legacy("psbench.render:MODELS") or ())}


def wps_weights() -> dict:
    return {w: "" for w in (_legacy("psbench.solve.methods.wps:WEIGHTS") or ())}


def th_scopes() -> dict:
    return {s: "" for s in (_legacy("psbench.solve.masks:SCOPES") or ())}


def run_kinds() -> dict:
    """The built-in run kinds and those plug-ins register."""
    out = {"solve": "render or read a scene, solve it, score it",
           "cond": "condition value of the light layout (no images)",
           "analysis": "a registered analysis, stored as json"}
    out.update(_registry("run_kinds"))
    return out


def analyses() -> dict:
    """Registered ``kind=analysis`` computations (psbench's and plug-ins')."""
    return _registry("analyses")


def choice_sources() -> dict:
    """What ``psbench --help`` lists: title -> ``{name: help}``."""
    return {"masks": masks(), "methods": methods(), "surfaces": surfaces(),
            "models": models(), "WPS weights": wps_weights(), "experiments": experiments()}


def options_class(method):
    """The options dataclass of ``method`` (an unknown name lists the valid ones)."""
    from .. import registry

    return registry.get("methods", method).options


def check_surface(value, params):
    if os.path.isabs(value):
        if not Path(value).is_file():
            raise PsbenchError(f"surface file {value!r} does not exist")
        return
    valid = surfaces()
    if valid and value not in valid:
        raise PsbenchError(f"surface={value!r} is not known; valid choices: {', '.join(valid)} "
                           f"or a path to a .npy / 16-bit .png height map or an .x3p topography")


def check_data(value, params):
    if str(value).lower().endswith(".x3p"):
        raise PsbenchError(f"data={value!r} is a topography, not a folder of images; render "
                           f"it with surface={Path(value).name}")
    if not Path(value).is_dir():
        raise PsbenchError(f"data={value!r} is not a folder")


def check_lights(value, params):
    from ..lights import layout

    layout(value)


def check_mask(value, params):
    from .. import registry

    valid = masks()
    low = {n.lower(): n for n in valid}
    tokens = [t for t in value.replace("-", " ").replace("+", " ").split() if t.lower() != "none"]
    for t in tokens:
        if t.lower() not in low:
            raise PsbenchError(f"mask={value!r}: unknown mask {t!r}; valid masks: None, "
                               f"{', '.join(valid)} (combine with '-', e.g. 'Th-Hi-Re-Sh')")
    specs = registry.masks()
    fusing = [low[t.lower()] for t in tokens if getattr(specs.get(low[t.lower()]), "fuses", False)]
    if fusing and len(set(t.lower() for t in tokens)) > 1:
        raise PsbenchError(f"mask={value!r}: {fusing[0]} fuses its own subset solutions and "
                           f"cannot be combined with other masks; use mask='{fusing[0]}'")


def check_analysis(value, params):
    valid = analyses()
    if value not in valid:
        raise PsbenchError(f"analysis={value!r} is not a registered analysis; valid: "
                           f"{', '.join(valid)}")
