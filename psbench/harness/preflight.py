"""Checks of a set of runs before any of them does work.

A configuration error (a bad value, a mask that needs another image count, WPS on one
ring, a threshold out of range, ...) must be refused with one line and exit status 2,
never computed and never stored as a failed row. Most of these are found by the very
functions a run calls (``make_surface``, ``layout``, ``render``, ``solve``), so instead of
copying their checks, :func:`preflight` runs each distinct configuration once on a
16 x 16 miniature of its scene (a *dry run*, milliseconds; a surface whose
``SurfaceSpec.min_size`` is larger, such as the cartridge case, at that size) and turns their
:class:`~psbench.PsbenchError` into a refusal. Errors that only real data can show
(an unreadable image, a method diverging) happen during the run and are stored as
failed rows, as before.

It also checks that the store is writable and that each run can fit in the memory
available to this process (:func:`memory_estimate`).
"""
from __future__ import annotations

import json
import os
import warnings
from pathlib import Path

from .._shared.checks import PsbenchError
from .params import validate

__all__ = ["preflight", "dry_run", "memory_estimate", "available_memory", "MINI"]

#: side of the miniature scenes of dry runs
MINI = 16
#: peak memory of a run beyond the interpreter, in image stacks (k x H x W float32),
#: measured with ``peak_mem_mb`` at 512 px: 9.6 (default run) to 15 (robust); the
#: lower end is used, so that only runs that cannot fit are refused
_STACKS = 8.0
_BASE_MB = 120.0


def _describe(p, keys=("surface", "data", "size", "lights", "mask", "method")):
    parts = [f"{k}={p[k]}" for k in keys if p.get(k) not in (None, {}, [])]
    return " ".join(parts)


def preflight(runs, *, root=None, sweep=None, memory=True) -> None:
    """Refuse, before any work, runs that cannot succeed whatever the data.

    Parameters
    ----------
    runs : list of dict
        Normalized run parameters.
    root, sweep : optional
        The store and folder the rows go to: checked writable when given.
    memory : bool
        Refuse runs whose :func:`memory_estimate` exceeds :func:`available_memory`.

    Raises
    ------
    PsbenchError
        One line naming the parameter (and the run when there are several).
    """
    if root is not None:
        from .store import check_writable

        check_writable(root, sweep)
    seen, scenes = set(), {}
    avail = available_memory() if memory else None
    for p in runs:
        key = _key(p, exclude=("seed", "extras"))
        if key in seen:
            continue
        seen.add(key)
        try:
            validate(p)
            dry_run(p, scenes=scenes, seen=seen)
        except PsbenchError as exc:
            where = f" (run {_describe(p)})" if len(runs) > 1 else ""
            raise PsbenchError(f"{exc}{where}") from None
        if avail is not None:
            need = memory_estimate(p)
            if need is not None and need > avail[0]:
                raise PsbenchError(_memory_message(p, need, avail))


def _key(p, keep=None, exclude=()):
    return json.dumps({k: v for k, v in p.items() if (keep is None or k in keep)
                       and k not in exclude}, sort_keys=True, default=str)


#: what a solve's configuration checks depend on (its scene: only through the lights)
_SOLVE = ("kind", "mask", "method", "weighted", "weight", "binary", "options", "thresholds",
          "th_scope", "lights", "data")
_SCENE = ("surface", "data", "lights", "model", "shadows", "noise", "quantize")


def dry_run(p, *, scenes=None, seen=None) -> None:
    """Call what run ``p`` calls, on a 16 x 16 miniature of its scene; raises the
    :class:`~psbench.PsbenchError` the real run would raise for its configuration.

    ``scenes`` (a dict) caches the miniature scenes and ``seen`` (a set) the solve
    configurations already checked, across the runs of a grid."""
    if p["kind"] == "cond":
        from ..lights import layout

        layout(p["lights"])
        return
    if p["kind"] != "solve":
        return                      # analysis functions and noop runs: names only
    scenes = {} if scenes is None else scenes
    if p["data"] is None and p["surface"].lower().endswith(".x3p"):
        from ..surfaces import read_topography

        read_topography(p["surface"])  # a damaged or foreign file: refused before any work
    if p["data"] is None and not os.path.isabs(p["surface"]):
        from ..surfaces._surface import check_size

        check_size(p["size"])
        if p["size"] < _min_size(p["surface"]):
            from ..surfaces import make_surface

            make_surface(p["surface"], size=p["size"])  # raises the surface's own refusal
    skey = _key(p, keep=_SCENE)
    if skey not in scenes:
        scenes[skey] = _mini_scene(p)
    mini = scenes[skey]
    if mini is None:
        return
    vkey = "solve:" + _key(p, keep=_SOLVE)
    if seen is not None:
        if vkey in seen:
            return
        seen.add(vkey)
    from .run import solve_run

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        solve_run(p, *mini, rounds=1)


def _mini_scene(p):
    """(images, lights, object_mask) of run ``p``'s scene at 16 x 16 (None when a data
    folder's lights cannot be read cheaply)."""
    from ..lights import layout
    from ..render.scene import render
    from ..surfaces import make_surface

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if p["data"] is None:
            s = p["surface"]
            # a height file is read by the run itself; its scene checks need no copy. A
            # surface that needs more pixels than MINI (a cartridge case) is built at its
            # smallest accepted size
            mini = (make_surface("semisphere", size=MINI) if os.path.isabs(s)
                    else make_surface(s, size=max(MINI, _min_size(s))))
            lay = layout(p["lights"])
            scene = render(mini, lay, model=p["model"], shadows=p["shadows"], noise=p["noise"],
                           seed=p["seed"], quantize=p["quantize"], **(p.get("render") or {}))
            return scene.images, lay, mini.object_mask
        lay = _data_lights(p["data"])
        if lay is None:
            return None
        mini = make_surface("semisphere", size=MINI)
        images = render(mini, lay, model="lambert").images
        if p["lights"] is not None:
            from .run import select_lights

            images, lay = select_lights(images, lay, p["lights"])
        return images, lay, mini.object_mask


def _min_size(name):
    """The smallest size surface ``name`` accepts (its ``SurfaceSpec.min_size``)."""
    from .. import registry

    return int(getattr(registry.get("surfaces", name, what="surface"), "min_size", MINI))


def _data_lights(folder):
    """The light layout of a data folder from its light_directions.txt (None when it
    cannot be read cheaply; the run then reports the problem)."""
    from ..io import read_lights
    from ..lights import layout

    f = Path(folder) / "light_directions.txt"
    if not f.is_file():
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return layout(read_lights(f))
    except PsbenchError:
        return None


# ---------------------------------------------------------------------------- memory
def memory_estimate(p):
    """Estimated peak memory of run ``p`` in MB (synthetic solve runs; None when the
    image size is unknown before reading, as for ``data=`` runs)."""
    if p.get("kind") != "solve" or p.get("data") is not None or p.get("size") is None:
        return None
    try:
        from ..lights import layout

        k = layout(p["lights"]).k
    except PsbenchError:
        return None
    stack = k * int(p["size"]) ** 2 * 4 / 2**20
    return _BASE_MB + _STACKS * stack


def _meminfo(key):
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def _status(key):
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith(key + ":"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    return None


def _cgroup():
    try:
        lim = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        cur = Path("/sys/fs/cgroup/memory.current").read_text().strip()
        if lim != "max":
            return (int(lim) - int(cur)) / 2**20
    except (OSError, ValueError):
        pass
    return None


def available_memory():
    """(MB this process can still allocate, what limits it) or None when unknown: the
    smallest of the address-space limit (``ulimit -v``) less what is mapped, the
    cgroup's memory limit less its use, and the machine's available memory and swap."""
    cands = []
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            cands.append((soft / 2**20 - (_status("VmSize") or 0.0),
                          f"the address-space limit (ulimit -v {soft // 1024})"))
    except (ImportError, OSError, ValueError):
        pass
    cg = _cgroup()
    if cg is not None:
        cands.append((cg, "the cgroup memory limit"))
    mem = _meminfo("MemAvailable")
    if mem is not None:
        cands.append((mem + (_meminfo("SwapFree") or 0.0), "the machine's free memory and swap"))
    return min(cands) if cands else None


def _memory_message(p, need, avail):
    have, what = avail
    from ..lights import layout

    k = layout(p["lights"]).k
    room = max(have - _BASE_MB, 0.0) * 2**20 / (_STACKS * k * 4)
    fits = int(room ** 0.5) // 16 * 16
    hint = f" (size={fits} fits)" if 16 <= fits < int(p["size"]) else ""
    return (f"run {_describe(p)} needs about {need / 1024:.1f} GB (estimated) but only "
            f"{max(have, 0) / 1024:.1f} GB is available under {what}; use a smaller "
            f"size={hint} or fewer lights, or allow more memory")
