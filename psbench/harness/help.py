"""``psbench --help``: usage, every run parameter and setting (from the run spec), the
valid choices (from the registries) and what the printed figures mean."""
from __future__ import annotations

import dataclasses
import re
import textwrap

from . import choices as C
from . import spec as S

__all__ = ["help_text", "option_help"]

WIDTH = 100
_SECTIONS = {C.masks: "masks", C.methods: "methods", C.surfaces: "surfaces",
             C.models: "render models", C.wps_weights: "WPS weights",
             C.experiments: "experiments"}

USAGE = """\
usage:
  psbench [KEY=VALUE ...]                one run: prints one row and stores it
  psbench -m KEY=A,B [KEY=X,Y ...]       a sweep over every combination (joblib, all cores)
  psbench +experiment=NAME [scale=ci]    a thesis experiment's grid, run in chunks
  psbench --help | --version | --cfg job | --hydra-help

examples:
  psbench surface=mozart lights=30x8+60x8 noise=0.1 mask=Th-Hi-Re-Sh weighted=true
  psbench mask=Th-Hi-Re-Sh options.max_iter=5 options.iter_tol=0
  psbench -m mask=Th,xNL,RA zenith=30,45,60
  psbench method=wps weight=eZsource lights=30x8+60x8
  psbench data=path/to/folder mask=Th
  psbench +experiment=table5_3 scale=ci jobs=2
"""

FIGURES = """\
figures (printed row and store columns):
  NE  normal error: angle between the estimated and the true normal, in degrees (Eq. 2.28);
      ne_mean, ne_median over the object, ne_lt5/10/20 the fraction of pixels under 5/10/20
      degrees. Needs true normals (rendered scenes, data folders that have them).
  IE  intensity error: residual i - rho s.n of each image (linear Lambert prediction) per
      pixel, as L1 (mean |r|), L2 (RMS) and Linf (max |r|) over the images, averaged over
      the object, in image intensity units (Eqs. 2.29-2.31); ie_rel = IE L2 in % of the
      images' mean dynamic range; ie_weighted the ring-weighted IE of WPS (Eq. 2.30).
  QF  quality factor of a mask, 0-1: TP / (TP + FP + FN) of the observations it drops
      against the true highlights (qf_hi), shadows (qf_sh) and both (qf_total); 1 = exact
      (Eq. 2.32; rendered scenes only); qf_sr against the observations whose true
      secondary fraction exceeds t_sr (scenes rendered with bounces > 0).
  times in seconds: render (or read) the images, solve, total.
"""

FOOTER = """\
Rows go to <results_dir>/runs/<sweep or experiment>/<run_id>.parquet; a stored run is
skipped unless rerun=true (failed ones: retry_failed=true). psbench-results inspects and
compacts the store, psbench-report rebuilds reports/. --cfg job prints the composed
configuration; --hydra-help lists Hydra's own options (launchers: hydra/launcher=...).
"""


def _value(v) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, dict):
        return "{}" if not v else "{...}"
    if isinstance(v, list):
        return "[" + ",".join(map(str, v)) + "]"
    return str(v)


def _wrap(text, indent, first=""):
    return textwrap.fill(text, WIDTH, initial_indent=first or indent, subsequent_indent=indent,
                         break_on_hyphens=False)


def _param_lines(params) -> list[str]:
    lines = []
    for p in params:
        key = f"{p.name}={_value(p.default) if p.default is not None or not p.metavar else p.metavar}"
        text = p.help
        if isinstance(p.choices, tuple):
            text += "; one of: " + ", ".join(p.choices)
        elif p.choices is not None:
            section = _SECTIONS.get(p.choices)
            if section:
                text += f" (see {section} below)"
            else:
                names = p.names()
                if names:
                    text += "; one of: " + ", ".join(names)
        first = f"  {key:<22}"
        if len(first) > 24:
            lines.append(first.rstrip())
            first = " " * 24
        lines.append(_wrap(text, " " * 24, first))
    return lines


def option_help(cls) -> dict[str, str]:
    """``{field: description}`` from the numpydoc ``Parameters`` section of an options
    class (a line ``a, b, c`` documents several fields at once)."""
    doc = cls.__doc__ or ""
    m = re.search(r"\n\s*Parameters\n\s*-+\n(.*?)(\n\s*\n\s*\w[\w ]*\n\s*-+\n|\Z)", doc, re.S)
    if not m:
        return {}
    lines = [ln for ln in m.group(1).split("\n") if ln.strip()]
    indent = min((len(ln) - len(ln.lstrip()) for ln in lines), default=0)
    out, names = {}, []
    for ln in lines:
        if len(ln) - len(ln.lstrip()) == indent:
            names = [n.strip() for n in ln.strip().split(" : ")[0].split(",") if n.strip()]
            continue
        for n in names:
            out[n] = (out.get(n, "") + " " + ln.strip()).strip()
    return {k: v.replace("``", "") for k, v in out.items()}


def _fields(cls):
    return list(dataclasses.fields(cls)) if dataclasses.is_dataclass(cls) else []


def _default(f):
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def _option_lines(cls, names, indent):
    """One entry per option (options sharing a description share an entry)."""
    docs = option_help(cls)
    groups = []                                   # [(keys, text)]
    for f in _fields(cls):
        if f.name not in names:
            continue
        key, text = f"{f.name}={_value(_default(f))}", docs.get(f.name, "")
        if groups and text and groups[-1][1] == text:
            groups[-1][0].append(key)
        else:
            groups.append(([key], text))
    lines, col = [], len(indent) + 26
    for keys, text in groups:
        head = indent + " ".join(keys)
        if len(head) > col - 2 or not text:
            lines.append(head)
            if text:
                lines.append(_wrap(text, " " * col))
        else:
            lines.append(_wrap(text, " " * col, f"{head:<{col}}"))
    return lines


def _methods_block() -> list[str]:
    from .. import registry
    from ..solve.base import Options

    engine = [f.name for f in _fields(Options) if f.name not in S.SPEC]
    out = ["methods (method=NAME) and their options (options.NAME=VALUE on the command line,",
           "checked by the method's options class before anything runs):"]
    specs = registry.methods()
    if not specs:
        names = C.methods()
        if not names:
            return out + ["  (none registered)"]
        out.append(_wrap(", ".join(names), "  "))
        out.append("  options of the mask engine (options.NAME=VALUE):")
        return out + _option_lines(Options, engine, "    ")
    shared = False
    for name in sorted(specs, key=str.lower):
        m = specs[name]
        out.append(_wrap(f"{name:<10}{m.help}", " " * 12, "  "))
        cls = m.options
        sub = isinstance(cls, type) and issubclass(cls, Options)
        shared |= sub
        own = [f.name for f in _fields(cls)
               if f.name not in S.SPEC and not (sub and f.name in engine)]
        if sub:
            out.append("            options: the mask engine's (below)" + (", and:" if own else ""))
        out.extend(_option_lines(cls, own, "            "))
    if shared:
        out.append("  options of the mask engine, shared by every method built on it "
                   "(options.NAME=VALUE):")
        out.extend(_option_lines(Options, engine, "    "))
    return out


def _masks_block() -> list[str]:
    """Masks by stage of Fig. 3.1 (image, subset, normal), each with its help."""
    from .. import registry

    title = "masks (mask=EXPR: names joined by '-', e.g. Th-Hi-Re-Sh; None: no mask)"
    specs = registry.masks()
    if not specs:
        return _choice_block(title, C.masks())
    order = {"image": 0, "subset": 1, "normal": 2}
    names = sorted(specs, key=lambda n: (order.get(specs[n].stage, 3), n.lower()))
    w = max(len(n) for n in names) + 2
    out = [f"{title}:"]
    for n in names:
        m = specs[n]
        out.append(_wrap(f"{n:<{w}}{m.stage + ':':<8}{m.help}", " " * (w + 10), "  "))
    return out


def _choice_block(title, names) -> list[str]:
    if not names:
        return [f"{title}: (none registered)"]
    if any(names.values()):
        w = max(len(n) for n in names) + 2
        return [f"{title}:"] + [_wrap(f"{n:<{w}}{h}", " " * (w + 2), "  ") for n, h in
                                names.items()]
    return [f"{title}:", _wrap(", ".join(names), "  ")]


def help_text() -> str:
    """The full ``psbench --help`` text (registries read now)."""
    import psbench

    parts = [f"psbench {psbench.__version__}: photometric stereo benchmark runs (render or "
             f"read, solve, score, store).", "", USAGE,
             "run parameters (KEY=VALUE; together they identify a run):",
             *_param_lines(S.PARAMS), "",
             "harness settings (how runs execute and where rows go; not part of a run's "
             "identity):", *_param_lines(S.SETTINGS), "", FIGURES]
    parts += _masks_block()
    parts += [""] + _methods_block() + [""]
    parts += _choice_block("surfaces (surface=NAME, or a .npy / 16-bit .png height map, or an "
                           ".x3p topography)", C.surfaces())
    parts += _choice_block("render models (model=NAME)", C.models())
    parts += _choice_block("WPS weights (method=wps weight=NAME)", C.wps_weights())
    parts += _choice_block("experiments (+experiment=NAME [scale=ci])", C.experiments())
    parts += ["", FOOTER]
    return "\n".join(parts).rstrip() + "\n"
