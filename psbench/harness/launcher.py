"""The ``-m`` sweep launcher: Hydra's joblib launcher that survives a lost worker.

A pool worker killed from outside (the out-of-memory killer, ``kill -9``) breaks the
whole joblib pool (``TerminatedWorkerError``). This launcher then starts a new pool for
the jobs that did not return, as experiments do (:mod:`psbench.harness.shards`): each
job skips its run when the store already holds it, so only what is missing is computed.
One warning line names the jobs that were running when the worker was lost. It is
registered under Hydra's ``hydra/launcher=joblib`` name (:func:`register`), so
``hydra.launcher.n_jobs=N`` and the other joblib settings work as before.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from hydra_plugins.hydra_joblib_launcher import _core
from hydra_plugins.hydra_joblib_launcher.config import JobLibLauncherConf
from hydra_plugins.hydra_joblib_launcher.joblib_launcher import JoblibLauncher

__all__ = ["ResilientJoblibLauncher", "register", "POOL_RESTARTS"]

_PLUGIN_MODULE = "hydra_plugins.psbench_joblib"
#: pool restarts after a worker process was lost, before giving up
POOL_RESTARTS = 3


def _job(idx, overrides, started, *args):
    """A pool worker's job: leave a marker (its overrides) while it runs."""
    mark = Path(started) / str(idx)
    mark.write_text(" ".join(overrides))
    try:
        return idx, _core.execute_job(idx, overrides, *args)
    finally:
        mark.unlink(missing_ok=True)


class ResilientJoblibLauncher(JoblibLauncher):
    """:class:`JoblibLauncher` that restarts its pool when a worker is lost."""

    def launch(self, job_overrides, initial_job_idx):
        from hydra.core.singleton import Singleton
        from hydra.core.utils import configure_log, filter_overrides, setup_globals
        from joblib import Parallel, delayed

        setup_globals()
        configure_log(self.config.hydra.hydra_logging, self.config.hydra.verbose)
        Path(str(self.config.hydra.sweep.dir)).mkdir(parents=True, exist_ok=True)
        cfg = dict(self.joblib)
        cfg["backend"] = "loky"             # as Hydra's: threads are incompatible with Hydra
        _core.process_joblib_cfg(cfg)
        state = Singleton.get_state()
        jobs = {initial_job_idx + i: list(o) for i, o in enumerate(job_overrides)}
        done = {}
        with tempfile.TemporaryDirectory(prefix="psbench-sweep-jobs-") as started:
            for attempt in range(POOL_RESTARTS + 1):
                todo = [i for i in jobs if i not in done]
                par = Parallel(**cfg, return_as="generator_unordered")
                try:
                    for idx, ret in par(delayed(_job)(i, jobs[i], started, self.hydra_context,
                                                      self.config, self.task_function, state)
                                        for i in todo):
                        done[idx] = ret
                    break
                except Exception as exc:  # noqa: BLE001 - a worker process itself was lost
                    if not _lost_worker(exc) or attempt == POOL_RESTARTS:
                        raise
                    lost = sorted(Path(started).iterdir(), key=lambda p: int(p.name))
                    names = "; ".join(f"#{p.name} ({' '.join(filter_overrides(p.read_text().split()))})"
                                      for p in lost) or "unknown"
                    for p in lost:
                        p.unlink(missing_ok=True)
                    left = len(jobs) - len(done)
                    print(f"psbench: warning: a sweep worker process was lost "
                          f"({type(exc).__name__}) while running job {names}; restarting "
                          f"the pool for the {left} job(s) not done (stored runs are "
                          "skipped)", file=sys.stderr, flush=True)
        return [done[i] for i in sorted(jobs)]


def _lost_worker(exc) -> bool:
    """True for the errors of a pool whose worker process died."""
    from concurrent.futures.process import BrokenProcessPool

    from joblib.externals.loky.process_executor import TerminatedWorkerError

    return isinstance(exc, (TerminatedWorkerError, BrokenProcessPool))


def register() -> None:
    """Make ``hydra/launcher=joblib`` this launcher.

    Hydra's plugin discovery stores the joblib launcher's config when it first runs, so
    it is run first and the entry replaced after it."""
    from dataclasses import dataclass

    from hydra.core.config_store import ConfigStore
    from hydra.core.plugins import Plugins

    import importlib

    plugins = Plugins.instance()
    # Hydra instantiates launchers of hydra_plugins modules only; its scan misses
    # packages installed in editable mode, so the plugin class is registered here
    plugins.register(importlib.import_module(_PLUGIN_MODULE).ResilientJoblibLauncher)

    @dataclass
    class Conf(JobLibLauncherConf):
        _target_: str = f"{_PLUGIN_MODULE}.ResilientJoblibLauncher"

    ConfigStore.instance().store(group="hydra/launcher", name="joblib", node=Conf,
                                 provider="psbench")
