"""Checks of the ``psbench`` command line before Hydra starts anything.

- keys: a key that is not a run parameter or setting (``+nosie=0.3``) is refused,
  naming the closest valid key, instead of being carried along unused;
- the store: ``results_dir`` must be writable (Hydra writes its own output there
  first, and failing there printed four chained tracebacks);
- ``-m`` sweeps: every job is composed as Hydra will compose it and the whole set of
  runs goes through :func:`psbench.harness.preflight.preflight`, so that one bad job
  refuses the sweep before any run starts.

Each problem is one :class:`~psbench.PsbenchError` line; the command exits with 2.
"""
from __future__ import annotations

import difflib
import os
from functools import lru_cache
from pathlib import Path

from .._shared.checks import PsbenchError

__all__ = ["check_keys", "known_keys"]

# flags after which Hydra does something else than running the task
_OTHER_MODES = ("--cfg", "-c", "--info", "-i", "--shell-completion", "-sc", "--resolve",
                "--package", "-p", "--config-dir", "-cd", "--config-name", "-cn",
                "--config-path", "-cp", "--experimental-rerun", "--hydra-help")


def _compose(overrides=()):
    from hydra import compose, initialize_config_module

    from ._config import CONFIG_PATH

    with initialize_config_module(config_module=CONFIG_PATH.split("://", 1)[1],
                                  version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides))


@lru_cache(maxsize=1)
def known_keys() -> tuple:
    """Top-level keys of psbench's configuration: the run spec's parameters and
    settings, and whatever else the primary config (``psbench/conf/config.yaml``)
    defines besides Hydra's own settings."""
    from importlib.resources import files

    from omegaconf import OmegaConf

    from . import spec as S

    extra = OmegaConf.load(files("psbench.conf") / "config.yaml")
    return tuple(dict.fromkeys([p.name for p in S.PARAMS + S.SETTINGS]
                               + [k for k in extra if k not in ("defaults", "hydra")]))


def check_keys(cfg) -> None:
    """Refuse top-level keys the configuration does not define."""
    valid = known_keys()
    unknown = [k for k in cfg.keys() if k not in valid and k != "hydra"]
    if unknown:
        k = unknown[0]
        near = difflib.get_close_matches(k, valid, n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        raise PsbenchError(f"unknown key {k!r}{hint}; valid keys: {', '.join(valid)}")


def _precheck(argv, watch) -> None:
    """Check the command line ``argv`` (Hydra overrides and flags) before Hydra runs;
    records the sweep's runs in ``watch`` (``root``, ``runs``)."""
    if any(a.split("=", 1)[0] in _OTHER_MODES for a in argv):
        return
    multi = "-m" in argv or "--multirun" in argv
    from hydra.core.override_parser.overrides_parser import OverridesParser

    parser = OverridesParser.create()
    try:
        parsed = parser.parse_overrides([a for a in argv if not a.startswith("-")])
    except Exception:  # noqa: BLE001 - a syntax error: Hydra reports it in its own words
        return
    user = [o for o in parsed if not o.key_or_group.startswith("hydra")]
    valid = known_keys()
    for o in user:
        key = o.key_or_group.split(".", 1)[0]
        if "/" not in key and key not in valid:
            check_keys({key: None})
    from .store import check_writable

    if not multi:               # the task checks the rest; here what Hydra needs first
        given = [o for o in user if o.key_or_group == "results_dir"]
        root = given[-1].value() if given else None
        root = Path(str(root or os.environ.get("PSBENCH_RESULTS") or "results")).expanduser()
        check_writable(root if root.is_absolute() else Path.cwd() / root)
        return
    fixed = [o.input_line for o in user if not o.is_sweep_override()]
    swept = [o for o in user if o.is_sweep_override()]
    try:
        cfg0 = _compose(fixed)
    except Exception as exc:  # noqa: BLE001 - e.g. an unknown config group: Hydra says it
        if "Could not override" in str(exc) or "Key" in str(exc):
            raise PsbenchError(str(exc).splitlines()[0]) from None
        return
    check_keys(cfg0)
    root = Path(str(cfg0.results_dir)).expanduser()
    root = root if root.is_absolute() else Path.cwd() / root
    check_writable(root)
    watch["root"] = root
    if cfg0.get("experiment"):
        return
    _sweep(cfg0, swept, parser, root, watch, {o.key_or_group.split(".")[0] for o in user})


def _sweep(cfg0, swept, parser, root, watch, overridden):
    """Compose every job of a ``-m`` sweep and preflight its runs."""
    from hydra._internal.core_plugins.basic_sweeper import BasicSweeper
    from omegaconf import OmegaConf

    from . import spec as S
    from ._config import _base_params
    from .params import normalize, run_id
    from .preflight import preflight

    jobs = [j for batch in BasicSweeper.split_arguments(swept, None) for j in batch] \
        if swept else [[]]
    runs = {}
    for job in jobs:
        cfg = cfg0.copy()
        for line in job:
            o = parser.parse_override(line)
            if o.is_delete():
                return                      # rare forms: left to the jobs themselves
            OmegaConf.update(cfg, o.key_or_group, o.value(), force_add=True)
        check_keys(cfg)
        if cfg.get("experiment"):
            continue
        st = S.coerce_settings({"sweep": cfg.get("sweep")})
        try:
            p = normalize(_base_params(cfg, overridden=overridden), base_dir=Path.cwd())
        except PsbenchError as exc:
            raise PsbenchError(f"{exc} (job {' '.join(job)})") from None
        runs.setdefault(st["sweep"], []).append(p)
    for sweep, ps in runs.items():
        preflight(ps, root=root, sweep=sweep)
    watch["runs"] = {s: [run_id(p, root=root) for p in ps] for s, ps in runs.items()}
