"""Where psbench's Hydra configs live and the run parameters of a composed config
(shared by the CLI and its pre-Hydra checks)."""
from __future__ import annotations

from . import spec as S

CONFIG_PATH = "pkg://psbench.conf"


def _overridden(*keys) -> bool:
    from hydra.core.hydra_config import HydraConfig

    try:
        over = HydraConfig.get().overrides.task
    except ValueError:
        return False
    names = {o.lstrip("+~").split("=", 1)[0] for o in over}
    return any(k in names for k in keys)


def _base_params(cfg, overridden=None) -> dict:
    """The run parameters of ``cfg``; ``overridden``: the keys set on the command line
    (default: read from Hydra's config of the running job)."""
    from omegaconf import OmegaConf

    c = OmegaConf.to_container(cfg, resolve=True)
    base = {k: c.get(k) for k in S.param_names(aliases=True)}
    given = (_overridden("lights", "zenith", "count") if overridden is None
             else bool({"lights", "zenith", "count"} & set(overridden)))
    if c.get("data") is not None and not given:
        base.pop("lights")           # a data folder uses all its lights by default
        base.pop("zenith")
        base.pop("count")
    return base
