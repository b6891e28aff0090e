"""One run: parameters -> scene (render or read) -> solve -> metrics -> results row.

Run parameters (:data:`PARAMS`, defaults below) fully determine a run; their
normalized json hashes to the ``run_id``. Kinds:

- ``solve`` (default): render ``surface`` (a name of :data:`psbench.SURFACES` or a
  ``.npy`` / 16-bit ``.png`` height map) under ``lights`` -- or read the folder
  ``data`` (DiLiGenT layout) -- then solve with ``mask``/``method``/... and score
  NE (when true normals exist), IE and QF (synthetic only). ``extras: [ne_by_zenith]``
  adds the NE-vs-surface-zenith curve (json) to the row.
- ``cond``: condition value of the layout ``lights`` (Table 2.1), no images.
- ``analysis``: calls ``psbench.analysis.<analysis>`` with the run parameters its
  signature accepts plus ``args``; its output is stored as json in ``payload``.
- ``noop``: harness self-test, computes nothing (``args: {fail: msg, sleep: s, die: true}``;
  ``die`` kills the process running it: only for tests of worker crashes).

Runs sharing a scene (:func:`scene_key`) reuse one rendered scene in
:func:`run_chunk`.
"""
from __future__ import annotations

import hashlib
import inspect
import json
import math
import os
import platform
import socket
import subprocess
import sys
import time
import traceback
from functools import lru_cache
from pathlib import Path

import numpy as np

from .._checks import PsbenchError

__all__ = ["PARAMS", "KINDS", "EXTRAS", "normalize", "run_id", "scene_key", "validate",
           "execute", "run_chunk", "format_row", "provenance"]

PARAMS = dict(kind="solve", surface="sombrero2", data=None, lights="45x8", model="ts",
              shadows=True, noise=0.05, quantize=None, size=512, mask="Th", weighted=False,
              method="ps", weight=None, binary=False, thresholds={}, th_scope="image",
              seed=0, analysis=None, args={}, extras=[])
KINDS = ("solve", "cond", "analysis", "noop")
EXTRAS = ("ne_by_zenith",)
_SCENE = ("kind", "surface", "data", "lights", "model", "shadows", "noise", "quantize",
          "size", "seed")
_SYNTH_ONLY = ("surface", "lights", "model", "shadows", "noise", "quantize", "size")


# ---------------------------------------------------------------------------- params
def _plain(value):
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


def _is_path(s) -> bool:
    s = str(s)
    return s.lower().endswith((".npy", ".png")) or "/" in s or os.sep in s


def _bool(v, name):
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, str) and v.lower() in ("true", "false"):
        return v.lower() == "true"
    if isinstance(v, (int, np.integer)) and v in (0, 1):
        return bool(v)
    raise PsbenchError(f"{name} must be true or false, got {v!r}")


def _int(v, name, *, allow_none=False):
    if v is None and allow_none:
        return None
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be an integer, got {v!r}") from None
    if isinstance(v, bool) or not f.is_integer():
        raise PsbenchError(f"{name} must be an integer, got {v!r}")
    return int(f)


def _float(v, name):
    try:
        f = float(v)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be a number, got {v!r}") from None
    if isinstance(v, bool) or not math.isfinite(f):
        raise PsbenchError(f"{name} must be a finite number, got {v!r}")
    return f


def normalize(params: dict, *, base_dir=None) -> dict:
    """Complete and canonicalize run parameters (the run's identity).

    Unknown keys are refused (listing the valid ones). ``zenith``/``count`` are
    accepted and turned into ``lights = "<zenith>x<count>"`` when ``lights`` is not
    given. Paths (``data``, file ``surface``) become absolute (relative to
    ``base_dir`` or the CWD). Parameters that cannot affect the run are set to None
    (e.g. render options of a ``data`` run), so they do not change the run_id.
    """
    p = {k: _plain(v) for k, v in dict(params).items()}
    zen, cnt = p.pop("zenith", None), p.pop("count", None)
    unknown = sorted(set(p) - set(PARAMS))
    if unknown:
        raise PsbenchError(f"unknown run parameter(s) {unknown}; valid: "
                           f"{', '.join(list(PARAMS) + ['zenith', 'count'])}")
    if p.get("lights") is None and zen is not None:
        p["lights"] = f"{_num(zen)}x{_int(cnt if cnt is not None else 8, 'count')}"
    explicit_lights = p.get("lights") is not None
    out = {k: p.get(k, v) for k, v in PARAMS.items()}
    out = {k: (json.loads(json.dumps(v)) if isinstance(v, (dict, list)) else v)
           for k, v in out.items()}
    base = Path(base_dir) if base_dir is not None else Path.cwd()

    kind = str(out["kind"])
    if kind not in KINDS:
        raise PsbenchError(f"kind={kind!r} is not known; valid choices: {', '.join(KINDS)}")
    out["kind"] = kind
    if out["data"] is not None:
        out["data"] = str((base / Path(str(out["data"])).expanduser()).resolve())
        lights = str(out["lights"]).replace(" ", "") if explicit_lights else None
        for k in _SYNTH_ONLY:
            out[k] = None
        out["lights"] = lights   # a layout selects the nearest of the folder's lights
    else:
        s = str(out["surface"])
        out["surface"] = str((base / Path(s).expanduser()).resolve()) if _is_path(s) else s
        out["lights"] = str(out["lights"]).replace(" ", "")
        out["model"] = str(out["model"])
        sh = out["shadows"]
        if isinstance(sh, str) and sh.lower() in ("all", "self", "none"):
            sh = {"all": True, "self": False, "none": "none"}[sh.lower()]
        out["shadows"] = sh if sh == "none" else _bool(sh, "shadows")
        out["noise"] = _float(out["noise"], "noise")
        out["quantize"] = _int(out["quantize"], "quantize", allow_none=True)
        out["size"] = None if _is_path(s) else _int(out["size"], "size")
    out["mask"] = str(out["mask"])
    out["weighted"] = _bool(out["weighted"], "weighted")
    out["method"] = str(out["method"])
    out["weight"] = None if out["weight"] is None else str(out["weight"])
    out["binary"] = _bool(out["binary"], "binary")
    out["th_scope"] = str(out["th_scope"])
    out["seed"] = _int(out["seed"], "seed")
    for k in ("thresholds", "args"):
        v = out[k] or {}
        if not isinstance(v, dict):
            raise PsbenchError(f"{k} must be a mapping, got {v!r}")
        out[k] = {str(a): v[a] for a in sorted(v)}
    ex = out["extras"] or []
    ex = [ex] if isinstance(ex, str) else list(ex)
    for e in ex:
        if e not in EXTRAS:
            raise PsbenchError(f"extras entry {e!r} is not known; valid choices: {', '.join(EXTRAS)}")
    out["extras"] = sorted(set(ex))
    if kind == "cond":
        out = {k: (v if k in ("kind", "lights") else PARAMS[k] if k in ("thresholds", "args", "extras")
                   else None) for k, v in out.items()}
        if out["lights"] is None:
            raise PsbenchError("kind=cond needs lights")
    if kind != "analysis":
        out["analysis"] = None
    elif not out["analysis"]:
        raise PsbenchError("kind=analysis needs analysis=<function name in psbench.analysis>")
    return out


def run_id(params: dict) -> str:
    """Stable 16-hex-digit hash of normalized parameters."""
    blob = json.dumps(params, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def scene_key(params: dict) -> tuple:
    """Runs with equal keys share one rendered (or read) scene."""
    return tuple(json.dumps(params.get(k), sort_keys=True) for k in _SCENE)


def validate(params: dict) -> None:
    """Cheap checks of names before any work (raises PsbenchError listing choices)."""
    from .. import lights as L

    kind = params["kind"]
    if kind == "noop":
        return
    if kind in ("solve", "analysis") and params["data"] is None:
        from ..surfaces import SURFACES

        s = params["surface"]
        if os.path.isabs(s):
            if not Path(s).is_file():
                raise PsbenchError(f"surface file {s!r} does not exist")
        elif s not in SURFACES:
            raise PsbenchError(f"surface={s!r} is not known; valid choices: "
                               f"{', '.join(SURFACES)} or a path to a .npy / 16-bit .png height map")
        from ..render import MODELS

        if params["model"] not in MODELS:
            raise PsbenchError(f"model={params['model']!r} is not known; valid choices: "
                               f"{', '.join(MODELS)}")
    if kind in ("solve", "analysis") and params["data"] is not None:
        if not Path(params["data"]).is_dir():
            raise PsbenchError(f"data={params['data']!r} is not a folder")
    if params["lights"] is not None:
        L.layout(params["lights"])
    if kind == "solve":
        from ..solve.api import METHODS, parse_mask
        from ..solve.masks import SCOPES

        parse_mask(params["mask"])
        if params["method"] not in METHODS:
            raise PsbenchError(f"method={params['method']!r} is not known; valid choices: "
                               f"{', '.join(METHODS)}")
        if params["th_scope"] not in SCOPES:
            raise PsbenchError(f"th_scope={params['th_scope']!r} is not known; valid choices: "
                               f"{', '.join(SCOPES)}")
    if kind == "analysis":
        _analysis_fn(params["analysis"])


def _analysis_fn(name):
    from .. import analysis

    fn = getattr(analysis, str(name), None)
    if name.startswith("_") or not callable(fn):
        names = sorted(n for n, v in vars(analysis).items() if callable(v) and not n.startswith("_")
                       and getattr(v, "__module__", "") == analysis.__name__)
        raise PsbenchError(f"analysis={name!r} is not a function of psbench.analysis; valid: "
                           f"{', '.join(names)}")
    return fn


# ---------------------------------------------------------------------------- provenance
@lru_cache(maxsize=1)
def _git():
    pkg = Path(__file__).resolve().parents[1]
    try:
        top = subprocess.run(["git", "-C", str(pkg), "rev-parse", "--show-toplevel"],
                             capture_output=True, text=True, timeout=10)
        if top.returncode != 0:
            return None, None
        root = Path(top.stdout.strip())
        if (root / "psbench" / "__init__.py").resolve() != (pkg / "__init__.py"):
            return None, None
        sha = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"],
                             capture_output=True, text=True, timeout=10).stdout.strip() or None
        st = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                             "--untracked-files=no"], capture_output=True, text=True, timeout=20)
        return sha, (bool(st.stdout.strip()) if st.returncode == 0 else None)
    except (OSError, subprocess.SubprocessError):
        return None, None


@lru_cache(maxsize=1)
def provenance() -> dict:
    """Provenance columns shared by every row written by this process."""
    from importlib import metadata

    import psbench

    libs = {"python": platform.python_version()}
    for name in ("numpy", "scipy", "opencv-python-headless", "pandas", "pyarrow", "hydra-core",
                 "omegaconf", "joblib", "submitit"):
        try:
            libs[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            libs[name] = None
    sha, dirty = _git()
    return dict(psbench_version=psbench.__version__, git_sha=sha, git_dirty=dirty,
                libs=json.dumps(libs, sort_keys=True), host=socket.gethostname())


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
        if p["data"] is not None:
            from ..io import read_dataset

            ds = read_dataset(p["data"])
            self.images, self.lights = ds.images, ds.lights
            if p["lights"] is not None:
                self.images, self.lights = select_lights(ds.images, ds.lights, p["lights"])
            self.mask = ds.mask
            self.normals = getattr(ds, "normals", None)
        else:
            from ..lights import layout
            from ..render import render
            from ..surfaces import make_surface, surface_from_file

            s = p["surface"]
            surf = surface_from_file(s) if os.path.isabs(s) else make_surface(s, size=p["size"])
            lay = layout(p["lights"])
            scene = render(surf, lay, model=p["model"], shadows=p["shadows"], noise=p["noise"],
                           seed=p["seed"], quantize=p["quantize"])
            self.images, self.lights, self.mask = scene.images, lay, surf.mask
            self.normals, self.truth = surf.normals, scene
        self.t_render = time.perf_counter() - t0
        self._dr = None

    def dynamic_range(self):
        """Mean image range over the object (cached: shared by the scene's runs)."""
        if self._dr is None:
            from ..metrics import dynamic_range

            self._dr = dynamic_range(self.images, self.mask)
        return self._dr


def select_lights(images, lights, spec):
    """Pick, for each light of the layout ``spec``, the nearest unused light of a data set.

    Returns the (k', H, W) images and a Layout with the data set's directions and the
    ring ids of ``spec`` (so multi-zenith methods see the rings).
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
    return np.ascontiguousarray(images[sel]), lay


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


def _solve_metrics(p, sc):
    from ..metrics import intensity_error, ne_by_zenith, normal_error_stats, quality_factor
    from ..solve import solve

    t0 = time.perf_counter()
    res = solve(sc.images, sc.lights, mask=p["mask"], method=p["method"], weighted=p["weighted"],
                object_mask=sc.mask, thresholds=p["thresholds"] or None, weight=p["weight"],
                binary=p["binary"], th_scope=p["th_scope"], seed=p["seed"])
    t_solve = time.perf_counter() - t0
    row = dict(t_solve=t_solve, n_images=int(sc.images.shape[0]), size=int(sc.images.shape[1]))
    if sc.normals is not None:
        st = normal_error_stats(res.normals, sc.normals, sc.mask)
        row.update({f"ne_{k}": _f(v) for k, v in st.items()})
        if "ne_by_zenith" in p["extras"]:
            row["ne_by_zenith"] = _json(ne_by_zenith(res.normals, sc.normals, sc.mask))
    for norm in ("l1", "l2", "linf"):
        row[f"ie_{norm}"] = _f(intensity_error(sc.images, res, sc.lights, norm=norm, mask=sc.mask))
    w = getattr(res, "ring_weights", None)
    if w is not None:
        row["ie_weighted"] = _f(intensity_error(sc.images, res, sc.lights, norm="l2",
                                                mask=sc.mask, weights=w))
    dr = sc.dynamic_range()
    row["ie_rel"] = _f(100.0 * row["ie_l2"] / dr) if row["ie_l2"] is not None and dr > 0 else None
    if sc.truth is not None and np.shape(res.valid) == np.shape(sc.images):
        qf = quality_factor(~np.asarray(res.valid, dtype=bool), sc.truth, sc.mask)
        row.update(qf_hi=_f(qf["hi"]), qf_sh=_f(qf["sh"]), qf_total=_f(qf["total"]))
    return row


def _analysis(p):
    fn = _analysis_fn(p["analysis"])
    sig = inspect.signature(fn)
    has_kw = any(q.kind == q.VAR_KEYWORD for q in sig.parameters.values())
    cand = {k: v for k, v in p.items()
            if k not in ("kind", "analysis", "args", "extras") and v is not None}
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


def execute(params, *, sweep="adhoc", experiment=None, cache=None, config=None) -> dict:
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
    """
    p = params
    row = {k: v for k, v in p.items() if k not in ("zenith", "count")}
    for k in ("thresholds", "args"):
        row[k] = json.dumps(p[k], sort_keys=True) if p[k] else None
    row["extras"] = json.dumps(p["extras"]) if p["extras"] else None
    if row.get("shadows") == "none":     # bool column: no shadows at all (exact value in config)
        row["shadows"] = False
    row.update(run_id=run_id(p), sweep=sweep, experiment=experiment, **provenance())
    row["config"] = json.dumps(config if config is not None else p, sort_keys=True, default=str)
    _layout_fields(p, row)
    _reset_peak()
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        validate(p)
        if p["kind"] == "noop":
            a = p["args"]
            if a.get("sleep"):
                time.sleep(float(a["sleep"]))
            if a.get("fail"):
                raise RuntimeError(str(a["fail"]))
            if a.get("die"):                      # simulate a worker killed mid-run
                import signal

                os.kill(os.getpid(), signal.SIGKILL)
            row.update(ne_mean=float(int(row["run_id"][:4], 16) % 100) / 10.0)
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
            row.update(_solve_metrics(p, sc))
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
        row = execute(p, sweep=sweep, experiment=experiment, cache=cache)
        _store_row(root, row)
        out.append({k: row.get(k) for k in ("run_id", "status", "error", "t_total")})
    return out


# ---------------------------------------------------------------------------- printing
def _fmt(v, spec=".2f"):
    return "-" if v is None or (isinstance(v, float) and not math.isfinite(v)) else format(v, spec)


def format_row(row) -> str:
    """One readable line: scene, lights, mask, method, NE, IE, QF, time, status."""
    r = {k: (None if _isna(v) else v) for k, v in dict(row).items()}
    if r.get("data"):
        what = f"data={Path(r['data']).name}"
    elif r.get("surface"):
        s = r["surface"]
        what = f"{Path(s).name if os.path.isabs(s) else s}@{r.get('size') or '?'}"
    else:
        what = r.get("kind") or "?"
    parts = [what]
    if r.get("lights") or r.get("n_images"):
        parts.append(f"lights={r.get('lights') or r.get('n_images')}")
    if r.get("kind") in (None, "solve"):
        if r.get("data") is None:
            parts.append(f"{r.get('model')} noise={_fmt(r.get('noise'), 'g')}")
        m = f"mask={r.get('mask')}"
        if r.get("weighted"):
            m += " weighted"
        meth = r.get("method") or "ps"
        if r.get("weight"):
            meth += f"/{r['weight']}"
        if r.get("binary"):
            meth += " binary"
        parts.append(f"{m} {meth}")
    if r.get("status") == "failed":
        parts.append(f"FAILED: {r.get('error')}")
    elif r.get("kind") == "cond":
        parts.append(f"cond={_fmt(r.get('cond'), '.3f')}")
    elif r.get("kind") == "analysis":
        parts.append(f"analysis={r.get('analysis')} payload={len(r.get('payload') or '')} chars")
    elif r.get("kind") in (None, "solve"):
        parts.append(f"NE {_fmt(r.get('ne_mean'))} deg (median {_fmt(r.get('ne_median'))})")
        parts.append(f"IE {_fmt(r.get('ie_l2'), '.4f')} ({_fmt(r.get('ie_rel'))} %)")
        if r.get("qf_total") is not None:
            parts.append(f"QF hi {_fmt(r.get('qf_hi'))} sh {_fmt(r.get('qf_sh'))} "
                         f"total {_fmt(r.get('qf_total'))}")
    parts.append(f"{_fmt(r.get('t_total'))} s (render {_fmt(r.get('t_render'))}, "
                 f"solve {_fmt(r.get('t_solve'))})")
    return " | ".join(parts)


def _isna(v):
    try:
        return v is None or (isinstance(v, float) and math.isnan(v))
    except TypeError:
        return False
