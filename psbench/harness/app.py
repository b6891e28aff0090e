"""The ``psbench`` command (Hydra app).

::

    psbench                                    # default scene: one run, one printed row
    psbench surface=semisphere lights=30x8+60x8 noise=0.1 mask=None
    psbench -m mask=Th,xNL,RA zenith=30,45,60  # sweep (joblib launcher, parallel)
    psbench data=path/to/folder mask=Th        # a DiLiGenT-layout folder
    psbench +experiment=table5_3 scale=ci      # an experiment grid, in-process chunks
    psbench mask=Th-Hi-Re-Sh options.max_iter=5    # method options
    psbench --help                             # every parameter, choice and figure

Run parameters and harness settings come from the run spec
(:mod:`psbench.harness.spec`), which generates Hydra's defaults; Hydra's own settings
ship inside the package (``psbench/conf``, loaded as ``pkg://psbench.conf``). Rows go to
``<results_dir>/runs/<sweep>/<run_id>.parquet`` (``results_dir`` defaults to
``$PSBENCH_RESULTS`` or ``results`` in the current directory); Hydra's own output goes
to ``<results_dir>/hydra/`` and nothing else is written to the current directory.
A run already stored is skipped ("skipped (stored)") unless ``rerun=true``; stored
failed runs are retried with ``retry_failed=true`` (single runs always retry them).
Errors in the configuration (an unknown key, surface or mask, a bad value, an
unwritable store, a run that cannot fit in memory) print one line and exit with code 2
before any work, and nothing is stored (:mod:`psbench.harness.checks`,
:mod:`psbench.harness.preflight`); a ``-m`` sweep is checked job by job first. Runs are
computed in supervised child processes (:mod:`psbench.harness.supervise`). Ctrl-C or
SIGTERM prints one line (how many runs are stored) and exits with code 130.
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import re
import signal
import sys
from pathlib import Path

from .._shared.checks import PsbenchError
from . import spec as S
from ._config import CONFIG_PATH, _base_params
from .checks import _precheck, check_keys
from .store import run_path

__all__ = ["main", "task"]

_EXIT = {"code": 0}
# what the command is computing: the store root and {sweep: run ids} (for Ctrl-C)
_WATCH = {}
# top-level config keys (from the run spec): "+key=value" is accepted for these too
# (not for experiment: "+experiment=NAME" selects a config group)
_KEYS = tuple(p.name for p in S.PARAMS + S.SETTINGS if p.name != "experiment")
# mapping parameters whose entries are set as "name.key=value" (Hydra needs "++")
_MAPPINGS = tuple(p.name for p in S.PARAMS if p.type == "mapping")
#: the one place Hydra's configs are loaded from


def _fix_argv(argv):
    """``+rerun=true`` -> ``++rerun=true`` for keys the config defines (Hydra refuses
    ``+`` for existing keys); ``[+]experiment=NAME`` -> ``++experiment=NAME`` (experiments
    come from the registry, not from a Hydra config group); everything else is left to
    Hydra."""
    out = []
    for a in argv:
        if "=" in a and a.lstrip("+").split("=", 1)[0] == "experiment":
            a = "++" + a.lstrip("+")
        elif a.startswith("+") and not a.startswith("++") and "=" in a:
            key = a[1:].split("=", 1)[0].split(".", 1)[0]
            if key in _KEYS:
                a = "+" + a
        out.append(a)
    return out


def _entries(argv):
    """``options.max_iter=5`` -> ``++options.max_iter=5``: entries of mapping parameters
    need no ``+`` on the command line."""
    out = []
    for a in argv:
        key = a.split("=", 1)[0]
        if "=" in a and "." in key and key.split(".", 1)[0] in _MAPPINGS:
            a = "++" + a
        out.append(a)
    return out


def _name_sweep(argv):
    """A ``-m`` sweep without ``sweep=`` is stored under a folder named from its swept
    parameters (``mask=Th,RA zenith=30,60`` -> ``mask=Th,RA_zenith=30,60``), so a second
    sweep does not overwrite the first one's rows folder, pictures or comparison sheet."""
    if not ("-m" in argv or "--multirun" in argv):
        return argv
    keys = [a.lstrip("+").split("=", 1)[0] for a in argv if "=" in a and not a.startswith("-")]
    if "sweep" in keys or "experiment" in keys:
        return argv
    from hydra.core.override_parser.overrides_parser import OverridesParser

    try:
        parsed = OverridesParser.create().parse_overrides(
            [a for a in argv if not a.startswith("-")])
    except Exception:  # noqa: BLE001 - a syntax error: Hydra reports it in its own words
        return argv
    parts = sorted(o.input_line.lstrip("+") for o in parsed      # sorted: same sweep, same name
                   if o.is_sweep_override() and not o.key_or_group.startswith("hydra"))
    if not parts:
        return argv
    name = re.sub(r"[^A-Za-z0-9._=,+-]+", "-", "_".join(parts)).strip("-")
    if len(name) > 80:                      # long value lists: a readable head + a hash
        name = name[:70] + "-" + hashlib.sha1(name.encode()).hexdigest()[:8]
    return argv + [f"sweep='{name}'"]           # quoted: '=' and ',' are Hydra syntax


def _multirun() -> bool:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    try:
        return HydraConfig.get().mode == RunMode.MULTIRUN
    except ValueError:
        return False


def _cwd() -> Path:
    from hydra.core.hydra_config import HydraConfig

    try:
        return Path(HydraConfig.get().runtime.cwd)
    except ValueError:
        return Path.cwd()


def _err(msg):
    print(f"psbench: error: {msg}", file=sys.stderr, flush=True)


def task(cfg):
    """Hydra task: one run (or an experiment when ``experiment`` is set)."""
    try:
        return _task(cfg)
    except PsbenchError as exc:
        _err(exc)
        _EXIT["code"] = 2
        return None


def _task(cfg):
    from omegaconf import OmegaConf

    from .params import normalize, run_id
    from .preflight import preflight
    from .run import format_row
    from .store import read_run, stored_status
    from .supervise import MAIN_PID_ENV, run_supervised, worker_setup

    multi = _multirun()
    if multi:
        worker_setup(os.environ.get(MAIN_PID_ENV))
    check_keys(cfg)
    root = Path(str(cfg.results_dir)).expanduser()
    if not root.is_absolute():
        root = _cwd() / root
    if cfg.get("experiment"):
        return _experiment(cfg, root)
    st = S.coerce_settings({k: cfg.get(k) for k in ("sweep", "rerun", "retry_failed")})
    params = normalize(_base_params(cfg), base_dir=_cwd())
    sweep = st["sweep"]
    rid = run_id(params, root=root)
    pics = _pictures_dir(cfg, root, sweep, rid, multi) if params["kind"] == "solve" else None
    done = {"run_id": rid, "root": str(root), "sweep": sweep,
            "out": None if pics is None else str(pics)}
    _WATCH.update(root=root, runs={sweep: [rid]})
    stored = stored_status(root, sweep, [rid]).get(rid) if not st["rerun"] else None
    skip = stored == "ok" or (multi and stored == "failed" and not st["retry_failed"])
    if skip:
        row = read_run(root, sweep, rid)
        line = format_row(row) if row is not None else rid
        print(f"skipped (stored{', failed' if stored == 'failed' else ''}): {line}", flush=True)
        if stored == "ok" and not _pictures_present(pics):
            _stored_pictures(cfg, root, sweep, rid, pics)
        return {**done, "status": stored, "skipped": True}
    preflight([params], root=root, sweep=sweep)     # configuration errors: before any work
    full = OmegaConf.to_container(cfg, resolve=True)
    full["results_dir"] = str(root)
    # the pictures are written by the process that computed the run, before its row is
    # stored: a stored "ok" row implies its pictures (unless outputs=none)
    after = None if pics is None else (lambda row, kept: _write_pictures(cfg, pics, row, kept))
    row = run_supervised([params], root=root, sweep=sweep,
                         config={"params": params, "cfg": full},
                         wrap=_one_line_warnings, after=after)[0]
    note = row.pop("_note", None)
    path = run_path(root, sweep, rid)
    print(f"{format_row(row)} | stored {path}", flush=True)
    if note:
        print(note, flush=True)
    if row["status"] != "ok":
        kind = row.get("exc_kind")
        if kind == "error":                       # a bug or numerical failure: show where
            print(row.get("traceback") or "", file=sys.stderr, flush=True)
        elif kind in ("memory", "killed"):        # the environment: one line
            _err(f"{row.get('error')} (the failed row is stored)")
        if not multi:
            _EXIT["code"] = 1 if kind == "error" else 2
    return {**done, "status": row["status"], "skipped": False}


# ------------------------------------------------------------ pictures (harness/outputs.py)
def _pictures_dir(cfg, root, sweep, rid, multi):
    """The run's picture folder (None: ``outputs=none``); refuses a foreign folder."""
    from . import outputs as O

    st = S.coerce_settings({k: cfg.get(k) for k in ("out", "outputs")})
    return O.run_dir(out=st["out"], outputs=st["outputs"], root=root, sweep=sweep,
                     run_id=rid, multi=multi, cwd=_cwd())


class _one_line_warnings:
    """psbench's own warnings (e.g. far lights) as one ``psbench: warning: ...`` line on
    stderr; other warnings are shown as Python shows them."""

    def __enter__(self):
        import warnings

        self._cm = warnings.catch_warnings(record=True)
        self._caught = self._cm.__enter__()
        return self

    def __exit__(self, *exc):
        import warnings

        from ..io import PsbenchWarning

        self._cm.__exit__(*exc)
        for w in self._caught:
            if issubclass(w.category, PsbenchWarning):
                print(f"psbench: warning: {w.message}", file=sys.stderr, flush=True)
            else:                       # one line too (psbench._warnings.one_line)
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)
        return False


def _stored_pictures(cfg, root, sweep, rid, pics):
    """``out=DIR`` on a stored run: copy the pictures written when it ran (they are in
    the default folder) into DIR; say how to make them when there are none."""
    from . import outputs as O

    default = O.sweep_dir(out=None, root=root, sweep=sweep, cwd=_cwd()) / rid
    if O.copy_stored(default, pics):
        print(f"pictures (stored run, copied from {default}/): {pics}/", flush=True)
        return
    print(f"no pictures in {pics}/ (the run was stored with outputs=none, or its pictures "
          f"were removed from {default}/): rerun=true makes them", flush=True)


def _pictures_present(pics):
    from . import outputs as O

    return O.present(pics)


def _write_pictures(cfg, pics, row, kept):
    """Write a run's pictures; returns the line saying where they went (None when the
    run has no result). Never fatal: a failure is one warning line and the row is
    stored all the same."""
    from . import outputs as O
    from .run import format_row

    if "result" not in kept:
        return None
    lvl = O.level(S.coerce_settings({"outputs": cfg.get("outputs")})["outputs"])
    try:
        secs = O.write_run(pics, lvl=lvl, row=row, result=kept["result"],
                           scene=kept["scene"], line=format_row(row))
    except Exception as exc:  # noqa: BLE001 - pictures must never cost the row
        print(f"psbench: warning: pictures not written to {pics}: {type(exc).__name__}: "
              f"{exc}", file=sys.stderr, flush=True)
        return None
    return f"pictures ({lvl}, {secs:.2f} s): {pics}/"


def _experiment(cfg, root):
    """Run a registered experiment's grid (``experiment=NAME``) in chunks."""
    from .. import registry
    from .grid import check_scale, expand, experiment_spec, load
    from .shards import execute_runs

    scale = str(cfg.scale)
    if isinstance(cfg.experiment, str):
        spec = registry.get("experiments", cfg.experiment, what="experiment")
        exp = load(spec.name, results_dir=root)
        check_scale(exp, scale)
        prepare = getattr(spec.module, "prepare", None)
        if prepare is not None:          # e.g. generated input folders, made once if missing
            prepare(root, scale)
    else:                                # an inline mapping (name, grids, fixed, scales)
        exp = experiment_spec(cfg.experiment)
    if int(cfg.jobs) == 0:
        raise PsbenchError("jobs=0: expected -1 (all cores), N >= 1 workers, or -N (all "
                           "cores but N-1)")
    runs = expand(exp, scale, _base_params(cfg), base_dir=_cwd())
    name = str(exp["name"])
    _refuse_ignored(cfg, runs, name, scale)
    from .params import run_id

    _WATCH.update(root=root, runs={name: [run_id(p, root=root) for p in runs]})
    print(f"experiment {name} (scale={cfg.scale}): {len(runs)} runs -> {root}/runs/{name}/",
          file=sys.stderr, flush=True)
    from omegaconf import OmegaConf

    sub = OmegaConf.to_container(cfg.submitit, resolve=True) if cfg.get("submitit") else {}
    out = execute_runs(runs, root=root, sweep=name, experiment=name, rerun=bool(cfg.rerun),
                       retry_failed=bool(cfg.retry_failed), jobs=int(cfg.jobs),
                       launcher=str(cfg.launcher), shards=int(cfg.shards), submitit=sub,
                       label=name)
    for r in out["results"] or []:
        if r["status"] != "ok":
            print(f"failed {r['run_id'] or '(a shard job: its runs are not stored)'}: "
                  f"{r['error']}", file=sys.stderr)
    if out["failed"]:
        _EXIT["code"] = 1
    return {k: v for k, v in out.items() if k != "results"}


def _refuse_ignored(cfg, runs, name, scale):
    """A run parameter given on the command line that the experiment's grid sets to
    another value (or ``sweep=``, the store folder being the experiment's) would be
    silently dropped: refused (one line) before any work."""
    from hydra.core.hydra_config import HydraConfig

    try:
        over = HydraConfig.get().overrides.task
    except ValueError:
        return
    given = {o.lstrip("+~").split("=", 1)[0]: o.split("=", 1)[-1] for o in over if "=" in o}
    if "sweep" in given:
        raise PsbenchError(f"sweep={given['sweep']}: experiments store their rows in "
                           f"runs/{name}/; leave sweep= out (it names command-line sweeps)")
    from .params import normalize

    params = {p.name for p in S.PARAMS}
    try:
        base = normalize(_base_params(cfg), base_dir=_cwd())
    except Exception:  # noqa: BLE001 - the runs' own checks (preflight) report bad values
        return
    for key, text in given.items():
        if key not in params or key not in base or not runs:
            continue
        vals = sorted({str(p.get(key)) for p in runs})
        if vals != [str(base[key])]:            # the grid set it: the value given is dropped
            shown = ", ".join(vals[:4]) + (" ..." if len(vals) > 4 else "")
            raise PsbenchError(f"{key}={text}: experiment {name} sets {key} itself (scale="
                               f"{scale}: {shown}); leave {key}= out, or choose another scale")


def main(args=None):
    """Console entry point ``psbench``.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments without the program name (default ``sys.argv[1:]``).
    """
    from .supervise import MAIN_PID_ENV

    from .._shared.warn import install

    install()                                     # warnings as one psbench line each
    args = list(sys.argv[1:] if args is None else args)
    if "--version" in args:
        import psbench

        print(f"psbench {psbench.__version__}")
        return
    if "--help" in args or "-h" in args:
        from .help import help_text

        sys.stdout.write(help_text())
        return
    argv = _name_sweep(_entries(_fix_argv(args)))
    sys.argv = [sys.argv[0]] + argv
    _EXIT["code"] = 0
    _WATCH.clear()
    os.environ[MAIN_PID_ENV] = str(os.getpid())   # pool workers follow this process
    old_term = restore = None
    try:
        old_term = _on_sigterm()
        restore = _sigint_here()
        import hydra

        S.register_hydra()
        from .launcher import register

        register()                     # -m: a pool that survives a lost worker
        try:
            _precheck(argv, _WATCH)
        except PsbenchError as exc:
            _err(exc)
            sys.exit(2)
        deco = hydra.main(version_base="1.3", config_path=CONFIG_PATH, config_name="config")
        deco(task)()
    except KeyboardInterrupt:
        _interrupted()
        sys.exit(130)
    finally:
        if restore is not None:
            restore()
        if old_term is not None:
            signal.signal(signal.SIGTERM, old_term)
    if _EXIT["code"]:
        sys.exit(_EXIT["code"])


def _on_sigterm():
    """SIGTERM (``kill``, ``timeout``, a scheduler) stops like Ctrl-C: one line, no
    temporary files, resumable."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        return None

    def stop(signum, frame):
        raise KeyboardInterrupt

    return signal.signal(signal.SIGTERM, stop)


def _sigint_here():
    """Ctrl-C reaches the whole process group; let it stop only this process.

    SIGINT is blocked while psbench runs (the mask is inherited by the run processes
    this process forks, so they never see it and print no traceback; pool workers
    leave Ctrl-C to this process once started, see ``worker_setup``) and a thread waits
    for it and raises KeyboardInterrupt in the main thread, which stops the pool, the
    run processes and reports. (Ignoring SIGINT instead would also cover pool workers
    still starting up, but a thread started earlier, e.g. by OpenBLAS, would then take
    the signal and drop it.) Returns the function restoring the previous state (None
    where signals cannot be managed this way)."""
    import threading

    if (threading.current_thread() is not threading.main_thread()
            or not hasattr(signal, "pthread_sigmask") or not hasattr(signal, "SIGUSR1")):
        return None
    old_mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    main_id = threading.main_thread().ident
    state = {"stop": False, "hit": False}

    def hit(signum, frame):        # in the main thread (also wakes a blocking wait)
        if state["hit"]:
            state["hit"] = False
            raise KeyboardInterrupt

    old_usr1 = signal.signal(signal.SIGUSR1, hit)

    def wait():
        while True:
            signal.sigwait({signal.SIGINT})
            if state["stop"]:
                return
            state["hit"] = True
            signal.pthread_kill(main_id, signal.SIGUSR1)

    t = threading.Thread(target=wait, name="psbench-sigint", daemon=True)
    t.start()

    def restore():
        state["stop"] = True
        with contextlib.suppress(Exception):
            signal.pthread_kill(t.ident, signal.SIGINT)
            t.join(1.0)
        signal.pthread_sigmask(signal.SIG_SETMASK, old_mask)
        signal.signal(signal.SIGUSR1, old_usr1)

    return restore


def _interrupted():
    """Ctrl-C: wait for the run processes to go, remove their temporary files, and say
    how much of the work is stored (it resumes from there)."""
    from .store import clean_temps, stored_status

    _wait_children()
    root = _WATCH.get("root")
    if root is None:
        print("\ninterrupted", file=sys.stderr, flush=True)
        return
    with contextlib.suppress(Exception):
        clean_temps(root, grace=0.0)          # writers on this host that are gone
    done = total = 0
    for sweep, ids in (_WATCH.get("runs") or {}).items():
        with contextlib.suppress(Exception):
            st = stored_status(root, sweep, ids if len(ids) < 64 else None)
            done += sum(1 for r in ids if r in st)
        total += len(ids)
    print(f"\ninterrupted: {done}/{total} stored; run the same command to resume",
          file=sys.stderr, flush=True)


def _wait_children(timeout=5.0):
    """Wait (a few seconds at most) for this process's children to exit.

    The resource trackers of joblib and multiprocessing are not waited for: they exit
    only after this process does, so waiting would always cost the whole timeout."""
    try:
        import psutil
    except ImportError:  # pragma: no cover - a declared dependency
        return
    with contextlib.suppress(Exception):
        kids = []
        for k in psutil.Process().children(recursive=True):
            with contextlib.suppress(psutil.Error):
                if "resource_tracker" not in " ".join(k.cmdline()):
                    kids.append(k)
        psutil.wait_procs(kids, timeout=timeout)


if __name__ == "__main__":  # pragma: no cover
    main()
