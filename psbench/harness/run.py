"""One run: parameters -> scene (render or read) -> solve -> metrics -> results row.

Run parameters are declared in the run spec (:mod:`psbench.harness.spec`) and
normalized by :func:`normalize`; their normalized json hashes to the ``run_id``. Kinds:

- ``solve`` (default): render ``surface`` (a registered surface name or a ``.npy`` /
  16-bit ``.png`` height map) under ``lights`` -- or read the folder ``data``
  (DiLiGenT layout) -- then solve with ``mask``/``method``/``options``/... and score
  NE (when true normals exist), IE and QF (synthetic only). ``extras: [ne_by_zenith]``
  adds the NE-vs-surface-zenith curve (json) to the row, ``ne_map`` the per-pixel NE
  map (small 16-bit PNG, :mod:`psbench.harness.nemap`).
- ``cond``: condition value of the layout ``lights`` (Table 2.1), no images.
- ``analysis``: calls the registered analysis ``analysis`` (psbench's in
  :mod:`psbench.analysis`, or a plug-in's: :class:`psbench.registry.Analysis`) with the
  run parameters its signature accepts plus ``args``; its output is stored as json in
  ``payload``.
- a plug-in's kind (:class:`psbench.registry.RunKind`, entry-point group
  ``psbench.run_kinds``): its function fills the row (the tests register ``noop``, a
  harness self-test, this way).

Runs sharing a scene (:func:`scene_key`) reuse one rendered scene in
:func:`run_chunk`.
"""
from __future__ import annotations

import inspect
import json
import math
import os
import socket
import sys
import time
import traceback
from functools import lru_cache
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError
from .._shared.deprecation import renamed_names
from . import spec as S
from .params import PARAMS, normalize, run_id, scene_key, validate
from .params import plain as _plain  # noqa: F401 - used by grid
from ._timing import pinned_threads, warm_up  # noqa: F401 - pinned_threads: public here

__all__ = ["PARAMS", "RUN_KINDS", "EXTRAS", "normalize", "run_id", "scene_key", "validate",
           "execute", "run_chunk", "format_row", "provenance", "select_lights", "solve_run",
           "base_row", "failed_row", "pinned_threads"]

RUN_KINDS, EXTRAS = S.RUN_KINDS, S.EXTRAS


# ---------------------------------------------------------------------------- provenance
@lru_cache(maxsize=1)
def provenance() -> dict:
    """Provenance columns shared by every row written by this process."""
    import psbench

    from .._shared.provenance import git_state, library_versions

    sha, dirty = git_state()
    return dict(psbench_version=psbench.__version__, git_sha=sha, git_dirty=dirty,
                libs=json.dumps(library_versions(), sort_keys=True), host=socket.gethostname())


# ---------------------------------------------------------------------------- memory
def _reset_peak():
    """Reset the kernel's peak-RSS counter of this process (Linux); best effort."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
    except OSError:
        pass


def _peak_mb():
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1]) / 1024.0
    except OSError:
        pass
    try:
        import resource

        r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        return r / (1024.0 * 1024.0) if sys.platform == "darwin" else r / 1024.0
    except Exception:  # noqa: BLE001
        return None


# ---------------------------------------------------------------------------- execution
class _Scene:
    """Images + truth of one scene (synthetic or read from a folder)."""

    def __init__(self, p):
        t0 = time.perf_counter()
        self.truth = None
        self.lights_read = None     # data runs with lights=: what select_lights picked
        self.pixel_size = None      # um per pixel when known: heights also go to height.x3p
        if p["data"] is not None:
            from ..io import read_dataset

            ds = read_dataset(p["data"])
            self.images, self.lights = ds.images, ds.lights
            if p["lights"] is not None:
                self.images, self.lights, self.lights_read = select_lights(
                    ds.images, ds.lights, p["lights"], report=True)
                _warn_far_lights(p["data"], self.lights_read)
            self.object_mask = ds.object_mask
            self.normals = getattr(ds, "normals", None)
            self.pixel_size = ds.meta.get("pixel_size_um")
        else:
            from ..lights import layout
            from ..render.scene import render
            from ..surfaces import make_surface, surface_from_file

            s = p["surface"]
            if s.lower().endswith(".x3p"):  # a measured topography: its pixel size is known
                from ..surfaces import read_topography, surface_from_topography

                topo = read_topography(s)
                surf, self.pixel_size = surface_from_topography(topo), topo.pixel_size
            else:
                surf = (surface_from_file(s) if os.path.isabs(s)
                        else make_surface(s, size=p["size"]))
                self.pixel_size = getattr(surf, "pixel_size", None)  # a cartridge case's
            lay = layout(p["lights"])
            scene = render(surf, lay, model=p["model"], shadows=p["shadows"], noise=p["noise"],
                           seed=p["seed"], quantize=p["quantize"], bounces=p.get("bounces") or 0,
                           **(p.get("render") or {}))
            self.images, self.lights, self.object_mask = scene.images, lay, surf.object_mask
            self.normals, self.truth = surf.normals, scene
        self.t_render = time.perf_counter() - t0
        self._dr = None

    def dynamic_range(self):
        """Mean image range over the object (cached: shared by the scene's runs)."""
        if self._dr is None:
            from ..metrics.errors import dynamic_range

            self._dr = dynamic_range(self.images, object_mask=self.object_mask)
        return self._dr


#: degrees: a requested light farther than this from the light used is warned about
FAR_LIGHT_DEG = 10.0


def select_lights(images, lights, spec, *, report=False):
    """Pick, for each light of the layout ``spec``, the nearest unused light of a data set.

    Returns the (k', H, W) images and a Layout with the data set's directions and the
    ring ids of ``spec`` (so multi-zenith methods see the rings); with ``report`` also a
    dict describing the match: ``requested`` (the spec), ``images`` (1-based numbers of
    the images used), ``off_deg`` (angle between each requested and used light),
    ``max_off_deg``, ``zenith_deg`` (of the lights used) and ``available`` (the data
    set's light count).
    """
    from ..lights import layout

    want = layout(spec)
    have = layout(lights)
    if want.k > have.k:
        raise PsbenchError(f"lights={spec!r} needs {want.k} lights, the data set has {have.k}")
    cos = want.directions @ have.directions.T
    idx = []
    for i in np.argsort(-cos.max(axis=1)):     # most certain matches first
        order = np.argsort(-cos[i])
        idx.append((i, next(j for j in order if j not in {b for _, b in idx})))
    idx.sort()
    sel = np.array([j for _, j in idx])
    lay = layout(have.directions[sel], power=have.power[sel], ring=want.ring)
    imgs = np.ascontiguousarray(images[sel])
    if not report:
        return imgs, lay
    off = np.degrees(np.arccos(np.clip(cos[np.arange(want.k), sel], -1.0, 1.0)))
    zen = np.degrees(np.arccos(np.clip(have.directions[sel, 2], -1.0, 1.0)))
    info = dict(requested=str(spec), images=[int(j) + 1 for j in sel],
                off_deg=[round(float(a), 2) for a in off], max_off_deg=round(float(off.max()), 2),
                zenith_deg=[round(float(z), 2) for z in zen], available=int(have.k))
    return imgs, lay, info


def _warn_far_lights(folder, info):
    """Warn when a requested light is more than :data:`FAR_LIGHT_DEG` from the one used."""
    if info["max_off_deg"] <= FAR_LIGHT_DEG:
        return
    import warnings

    from ..io import PsbenchWarning

    zen = info["zenith_deg"]
    far = sum(a > FAR_LIGHT_DEG for a in info["off_deg"])
    warnings.warn(f"lights={info['requested']}: {far} of the {len(zen)} lights used are more "
                  f"than {FAR_LIGHT_DEG:g} deg from the requested directions (up to "
                  f"{info['max_off_deg']:.1f} deg; the nearest of the {info['available']} "
                  f"lights of {Path(folder).name} have zeniths {min(zen):.0f}-{max(zen):.0f} "
                  "deg); the row records the lights used", PsbenchWarning, stacklevel=2)


def _json(obj):
    """json string of analysis outputs (DataFrames, arrays, dicts of them)."""
    import pandas as pd

    def conv(o):
        if isinstance(o, pd.DataFrame):
            return o.to_dict(orient="list")
        if isinstance(o, pd.Series):
            return o.to_list()
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, dict):
            return {str(k): conv(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [conv(v) for v in o]
        if hasattr(o, "__dict__") and not isinstance(o, type):
            return {k: conv(v) for k, v in vars(o).items() if not k.startswith("_")}
        return o

    return json.dumps(conv(obj), default=str, allow_nan=True)


def _f(v):
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def solve_run(p, images, lights, object_mask, *, rounds=None):
    """``psbench.solve`` called as run ``p`` calls it (the preflight's dry run calls this
    too, so both check the very same arguments; it caps the mask rounds at ``rounds``)."""
    from ..solve import solve

    kw = dict(p.get("options") or {})          # method options, checked by normalize()
    if rounds is not None:
        kw["max_iter"] = min(int(kw.get("max_iter", rounds)), rounds)
    if p["weight"] is not None:
        kw["weight"] = p["weight"]
    if p["binary"]:
        kw["binary"] = True
    return solve(images, lights, mask=p["mask"], method=p["method"], weighted=p["weighted"],
                 object_mask=object_mask, thresholds=p["thresholds"] or None,
                 th_scope=p["th_scope"], seed=p["seed"], **kw)


def _solve_metrics(p, sc, keep=None):
    from ..metrics.errors import (intensity_error, ne_by_zenith, normal_error_map,
                                  normal_error_stats, quality_factor)

    warm_up(solve_run, p, sc)
    t0 = time.perf_counter()
    res = solve_run(p, sc.images, sc.lights, sc.object_mask)
    t_solve = time.perf_counter() - t0
    if keep is not None:
        keep.update(result=res, scene=sc)
    row = dict(t_solve=t_solve, n_images=int(sc.images.shape[0]), size=int(sc.images.shape[1]))
    if sc.normals is not None:
        st = normal_error_stats(res.normals, sc.normals, object_mask=sc.object_mask)
        row.update({f"ne_{k}": _f(v) for k, v in st.items()})
        if "ne_by_zenith" in p["extras"]:
            row["ne_by_zenith"] = _json(ne_by_zenith(res.normals, sc.normals, object_mask=sc.object_mask))
        if "ne_map" in p["extras"]:
            from . import nemap
            row["ne_map"] = nemap.encode(normal_error_map(res.normals, sc.normals), sc.object_mask)
    for norm in ("l1", "l2", "linf"):
        row[f"ie_{norm}"] = _f(intensity_error(sc.images, res, sc.lights, norm=norm, object_mask=sc.object_mask))
    w = getattr(res, "ring_weights", None)
    if w is not None:
        row["ie_weighted"] = _f(intensity_error(sc.images, res, sc.lights, norm="l2",
                                                object_mask=sc.object_mask, weights=w))
    ve = getattr(res, "ve", None)
    if ve is not None:  # ground-truth-free validation error (psbench.solve.validation)
        row.update(ve_mean=_f(ve.mean), ve_median=_f(ve.median))
    fb = getattr(res, "fallback", None)
    if fb is not None:  # pixels that fell back to the simpler answer (solve.fallback)
        om = sc.object_mask if sc.object_mask is not None else np.ones(fb.shape, bool)
        row["fallback_fraction"] = _f(float(fb[om].mean()) if om.any() else 0.0)
    dr = sc.dynamic_range()
    row["ie_rel"] = _f(100.0 * row["ie_l2"] / dr) if row["ie_l2"] is not None and dr > 0 else None
    if sc.truth is not None and np.shape(res.valid) == np.shape(sc.images):
        qf = quality_factor(~np.asarray(res.valid, dtype=bool), sc.truth, object_mask=sc.object_mask)
        row.update(qf_hi=_f(qf["hi"]), qf_sh=_f(qf["sh"]), qf_total=_f(qf["total"]))
        if getattr(sc.truth, "bounces", 0):  # secondary light: the SR mask's truth
            row["qf_sr"] = _f(_qf_sr(res, sc))
    return row


def _qf_sr(res, sc):
    """QF of the masked observations against those whose true secondary fraction
    exceeds t_sr (the observations SR is meant to mask)."""
    from ..metrics.errors import quality_factor

    t = float(res.thresholds.get("t_sr", 0.5))
    pos = np.asarray(sc.truth.secondary_fraction) > t
    none = np.zeros_like(pos)
    qf = quality_factor(~np.asarray(res.valid, dtype=bool),
                        {"highlight": pos, "shadow": none}, object_mask=sc.object_mask)
    return qf["hi"]


def _analysis(p):
    from .. import registry

    fn = registry.get("analyses", p["analysis"], what="analysis").func   # validate() checked it
    sig = inspect.signature(fn)
    has_kw = any(q.kind == q.VAR_KEYWORD for q in sig.parameters.values())
    cand = {k: v for k, v in p.items() if k not in ("kind", "analysis", "args", "extras")
            and v is not None and not (k == "options" and not v)}
    derived = {}
    _layout_fields(p, derived)                 # zenith, count of a single ring
    cand.update({k: derived[k] for k in ("zenith", "count") if k in derived})
    kwargs = {k: v for k, v in cand.items() if has_kw or k in sig.parameters}
    for name in sig.parameters:                # plural parameters: zeniths=[zenith], ...
        if name not in kwargs and name.endswith("s") and name[:-1] in cand:
            kwargs[name] = [cand[name[:-1]]]
    kwargs.update(p["args"])
    return {"payload": _json(fn(**kwargs))}


def _layout_fields(p, row):
    if p.get("lights"):
        try:
            from ..lights import layout

            lay = layout(p["lights"])
            row.setdefault("n_images", lay.k)
            if lay.n_rings == 1:
                row["zenith"], row["count"] = float(lay.ring_zeniths[0]), int(lay.k)
        except Exception:  # noqa: BLE001 - bad specs fail later, with the real error
            pass


def execute(params, *, sweep="adhoc", experiment=None, cache=None, config=None,
            keep=None, root=None) -> dict:
    """Run once and return the complete results row (never raises for run errors).

    Parameters
    ----------
    params : dict
        Normalized run parameters (:func:`normalize`).
    sweep, experiment : str
        Store folder / experiment name written into the row.
    cache : dict, optional
        Scene cache shared by runs of a chunk (key :func:`scene_key`).
    config : dict, optional
        Extra json-able config to record (default: the parameters).
    keep : dict, optional
        Filled with the solve's ``result`` and its ``scene`` (for pictures).
    root : path-like, optional
        The results store the row goes to (its run id hashes paths inside it relative to
        it: :func:`~psbench.harness.params.run_id`).
    """
    p = params
    row = base_row(p, sweep=sweep, experiment=experiment, config=config, root=root)
    _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        with pinned_threads():
            _compute(p, row, cache, keep)
        row["status"] = "ok"
    except Exception as exc:  # noqa: BLE001 - a failing run is recorded, never fatal
        row["status"] = "failed"
        row["error"] = f"{type(exc).__name__}: {exc}"
        tb = traceback.extract_tb(exc.__traceback__)
        row["traceback"] = "".join(traceback.format_list(tb[-6:])) + row["error"]
        row["_exc"] = exc
    row["t_total"] = time.perf_counter() - t0
    row["t_cpu"] = time.process_time() - c0
    row["peak_mem_mb"] = _peak_mb()
    import datetime as _dt

    row["utc"] = _dt.datetime.now(_dt.timezone.utc)
    return row


def base_row(p, *, sweep="adhoc", experiment=None, config=None, root=None) -> dict:
    """The parameter, identity and provenance columns of run ``p``'s row."""
    row = {k: S.column_value(k, v) for k, v in p.items() if k in S.SPEC and not S.SPEC[k].alias}
    row.update(run_id=run_id(p, root=root), sweep=sweep, experiment=experiment, **provenance())
    row["config"] = json.dumps(config if config is not None else p, sort_keys=True, default=str)
    _layout_fields(p, row)
    return row


def failed_row(p, error, *, sweep="adhoc", experiment=None, config=None, root=None) -> dict:
    """The row of a run that ended without writing its own (its process was killed,
    e.g. by the out-of-memory killer)."""
    import datetime as _dt

    row = base_row(p, sweep=sweep, experiment=experiment, config=config, root=root)
    row.update(status="failed", error=str(error), traceback=str(error),
               utc=_dt.datetime.now(_dt.timezone.utc))
    return row


def _compute(p, row, cache, keep=None):
    """The work of one run; fills ``row``'s metric columns."""
    validate(p)
    if p["kind"] not in S.RUN_KINDS:             # a plug-in's kind
        S.plugin_kind(p["kind"]).func(p, row)
    elif p["kind"] == "cond":
        from ..lights import layout

        row["cond"] = _f(layout(p["lights"]).cond())
    elif p["kind"] == "analysis":
        row.update(_analysis(p))
    else:
        key = scene_key(p)
        sc = cache.get(key) if cache is not None else None
        if sc is None:
            sc = _Scene(p)
            if cache is not None:
                cache.clear()
                cache[key] = sc
            row["t_render"] = sc.t_render
        else:
            row["t_render"] = 0.0
        if sc.lights_read is not None:     # the lights actually used, with the row
            cfg = json.loads(row["config"])
            cfg["lights_read"] = sc.lights_read
            row["config"] = json.dumps(cfg, sort_keys=True, default=str)
        row.update(_solve_metrics(p, sc, keep))


def _store_row(root, row):
    from .store import write_row

    return write_row(root, {k: v for k, v in row.items() if not k.startswith("_")})


def run_chunk(chunk, *, root, sweep, experiment=None):
    """Run a list of normalized parameter dicts in this process, storing each row as it
    completes; scenes are shared between consecutive runs with equal :func:`scene_key`.

    Returns
    -------
    list of dict
        ``{"run_id", "status", "error", "t_total"}`` per run.
    """
    cache = {}
    out = []
    for p in sorted(chunk, key=scene_key):
        row = execute(p, sweep=sweep, experiment=experiment, cache=cache, root=root)
        _store_row(root, row)
        out.append({k: row.get(k) for k in ("run_id", "status", "error", "t_total")})
    return out


# ---------------------------------------------------------------------------- printing
def _fmt(v, spec=".2f"):
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def format_row(row) -> str:
    """One readable line that says what each figure is.

    Scene, lights, mask and method, then ``NE`` (mean angle between the estimated and
    true normals, degrees), ``IE`` (L2 Lambert residual, and in % of the images'
    dynamic range), ``QF`` (how well the mask matches the true highlights and shadows,
    0-1), times in seconds. A data folder's row says ``read`` where a rendered scene's
    says ``render``, and names the lights actually used when ``lights=`` picked them.
    """
    r = {k: (None if _isna(v) else v) for k, v in dict(row).items()}
    data = bool(r.get("data"))
    if data:
        what = f"data={Path(r['data']).name}"
    elif r.get("surface"):
        s = r["surface"]
        what = f"{Path(s).name if os.path.isabs(s) else s}@{r.get('size') or '?'}"
    else:
        what = r.get("kind") or "?"
    parts = [what]
    if data and r.get("kind") in (None, "solve"):
        parts.append(_lights_read_text(r))
    elif r.get("lights") or r.get("n_images"):
        parts.append(f"lights={r.get('lights') or r.get('n_images')}")
    if r.get("kind") in (None, "solve"):
        if not data:
            parts.append(f"{r.get('model')} noise={_fmt(r.get('noise'), 'g')}")
        m = f"mask={r.get('mask')}"
        if r.get("weighted"):
            m += " weighted"
        meth = r.get("method") or "ps"
        if r.get("weight"):
            meth += f"/{r['weight']}"
        if r.get("binary"):
            meth += " binary"
        opts = r.get("options")
        opts = json.loads(opts) if isinstance(opts, str) else opts
        if opts:
            meth += " " + " ".join(f"{k}={v}" for k, v in sorted(opts.items()))
        parts.append(f"{m} {meth}")
    if r.get("status") == "failed":
        parts.append(f"FAILED: {r.get('error')}")
    elif r.get("kind") == "cond":
        parts.append(f"cond={_fmt(r.get('cond'), '.3f')} (condition number of the lights)")
    elif r.get("kind") == "analysis":
        parts.append(f"analysis={r.get('analysis')} payload={len(r.get('payload') or '')} chars")
    elif r.get("kind") in (None, "solve"):
        if r.get("ne_mean") is None:
            parts.append("NE - (no ground truth)")
        else:
            parts.append(f"NE {_fmt(r.get('ne_mean'))}° mean angular error "
                         f"(median {_fmt(r.get('ne_median'))}°)")
        parts.append(f"IE {_fmt(r.get('ie_l2'), '.4f')} L2 Lambert residual "
                     f"({_fmt(r.get('ie_rel'))} % of range)")
        if r.get("qf_total") is not None:
            parts.append(f"QF {_fmt(r.get('qf_total'))} mask vs true highlights/shadows "
                         f"(hi {_fmt(r.get('qf_hi'))}, sh {_fmt(r.get('qf_sh'))})")
    parts.append(f"{_fmt(r.get('t_total'))} s ({'read' if data else 'render'} "
                 f"{_fmt(r.get('t_render'))}, solve {_fmt(r.get('t_solve'))})")
    return " | ".join(parts)


def _lights_read_text(r) -> str:
    """The lights of a data run: all of the folder's, or the ones ``lights=`` picked."""
    try:
        info = json.loads(r.get("config") or "{}").get("lights_read")
    except (TypeError, ValueError):
        info = None
    if info:
        return (f"lights={info['requested']} -> nearest {len(info['images'])} of "
                f"{info['available']} read (up to {info['max_off_deg']:.1f}° off)")
    if r.get("lights"):
        return f"lights={r['lights']} (nearest read)"
    return f"lights: all {r.get('n_images') or '?'} read"


def _isna(v):
    try:
        return v is None or (isinstance(v, float) and math.isnan(v))
    except TypeError:
        return False


__getattr__ = renamed_names(globals(), {"KINDS": "RUN_KINDS"})
