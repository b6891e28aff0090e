"""Library for experiment modules: build and read the long-format aggregates.

An experiment's :func:`aggregate` reduces its store rows (one per run) to a long frame
with columns :data:`LONG_COLUMNS` (``experiment, part, row, column, value, n``; ``n`` =
number of runs averaged), keyed like the thesis's values of the same cell. The helpers
here are shared by the built-in experiments (:mod:`psbench.experiments`) and open to
third-party ones:

- building: :func:`long_frame`, :func:`group_mean`, :func:`mean`;
- row labels: :func:`n_images`, :func:`model_label`, :func:`labels`, :func:`n_rings`,
  :func:`mask_family`, :func:`data_name`, :func:`weight_row`, :func:`fmt_num`;
- payloads stored as JSON: :func:`parse_json`, :func:`series_xy`, :func:`ie_components`;
- reading an aggregate: :func:`lookup`, :func:`series`.

This module imports nothing of psbench.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd

__all__ = ["LONG_COLUMNS", "long_frame", "mean", "group_mean", "fmt_num", "model_label",
           "labels", "n_images", "n_rings", "mask_family", "data_name", "weight_row",
           "parse_json", "series_xy", "ie_components", "lookup", "series"]

LONG_COLUMNS = ["experiment", "part", "row", "column", "value", "n"]


def long_frame(records, experiment: str = "") -> pd.DataFrame:
    """Long-format aggregate from ``(part, row, column, value, n)`` tuples."""
    df = pd.DataFrame.from_records(list(records), columns=["part", "row", "column", "value", "n"])
    df.insert(0, "experiment", experiment)
    return df


def mean(series) -> tuple[float, int]:
    """(mean, count) of the numeric, non-missing values of ``series``."""
    s = pd.to_numeric(series, errors="coerce").dropna()
    return (float(s.mean()) if len(s) else float("nan")), int(len(s))


def group_mean(df, keys, col, recs, part_fn, row_fn, col_fn):
    """Append ``(part, row, column, mean, n)`` per group of ``df`` by ``keys`` to ``recs``.

    ``part_fn``, ``row_fn`` and ``col_fn`` map the group key tuple to the cell's labels.
    """
    if df.empty or col not in df:
        return
    for k, g in df.groupby(keys, dropna=False, sort=True):
        k = k if isinstance(k, tuple) else (k,)
        v, n = mean(g[col])
        if n:
            recs.append((part_fn(k), row_fn(k), col_fn(k), v, n))


def fmt_num(x) -> str:
    """``45.0`` -> ``"45"``, ``0.1`` -> ``"0.1"`` (labels of numeric rows/columns)."""
    x = float(x)
    return str(int(x)) if x == int(x) else f"{x:g}"


def model_label(row) -> str:
    """Image kind of a row: ``Di`` (Lambert, no shadows), ``Di-Sh``, ``Hi`` or ``Hi-Sh``."""
    model = str(row.get("model") or "").lower()
    sh = row.get("shadows")
    if model == "lambert" and (sh is False or sh == 0 or (isinstance(sh, float) and sh == 0)):
        return "Di"
    if model == "lambert":
        return "Di-Sh"
    return "Hi-Sh" if bool(sh) else "Hi"


def labels(df, fn) -> pd.Series:
    """``fn(row_dict)`` for every row of ``df``, as an object Series."""
    return pd.Series([fn(r) for r in df.to_dict("records")], index=df.index, dtype=object)


def n_images(df) -> pd.Series:
    """Image count per row (``n_images``, else counted from the ``lights`` spec)."""
    n = pd.to_numeric(df.get("n_images"), errors="coerce") if "n_images" in df else None
    if n is None or n.isna().all():
        n = pd.Series([_count_from_lights(x) for x in df.get("lights", [])], index=df.index)
    return n


def _count_from_lights(spec) -> float:
    try:
        return float(sum(int(p.split("x")[1]) for p in str(spec).split("+")))
    except Exception:  # noqa: BLE001
        return float("nan")


def n_rings(spec) -> int:
    """Number of rings of a layout spec (``"30x8+60x8"`` -> 2)."""
    return len(str(spec).split("+")) if spec is not None else 0


def mask_family(mask: str) -> str:
    """NL and its extension xNL are one family in Figs. 5.12-5.14."""
    m = str(mask)
    if m.startswith("xNL"):
        return m[1:]
    return m


def data_name(path) -> str:
    """Last component of a data folder path (``.../diligent/cat`` -> ``cat``)."""
    p = str(path or "").rstrip("/")
    return p.split("/")[-1] if p else "?"


def weight_row(r) -> str:
    """Row label of a WPS weight (``"None"`` for ordinary PS)."""
    return str(r.get("weight")) if str(r.get("method") or "").lower() == "wps" else "None"


# ----------------------------------------------------------------------------- payloads

def parse_json(x):
    """A dict/list from a JSON string (None when missing or unreadable)."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return None
    if isinstance(x, (dict, list)):
        return x
    try:
        return json.loads(x)
    except Exception:  # noqa: BLE001
        return None


_X_KEYS = ("centers", "center", "zenith", "zeniths", "bins", "z", "x", "surface_zenith")
_EDGE_KEYS = ("edges", "bin_edges")


def series_xy(obj, y_keys=("ne", "mean", "values", "value", "y", "ne_mean")):
    """(x, y) arrays of a binned series stored as json in many plausible shapes.

    Accepts ``{"edges": [...], "ne": [...]}``, ``{"centers": [...], "mean": [...]}``,
    ``[[x, y], ...]`` or ``{"10": y, ...}``; returns None when nothing fits.
    """
    obj = parse_json(obj)
    if obj is None:
        return None
    if isinstance(obj, list):
        arr = np.asarray(obj, dtype=float)
        if arr.ndim == 2 and arr.shape[1] >= 2:
            return arr[:, 0], arr[:, 1]
        return None
    if not isinstance(obj, dict):
        return None
    y = None
    for k in y_keys:
        if k in obj and isinstance(obj[k], list):
            y = np.asarray(obj[k], dtype=float)
            break
    if y is None:
        try:
            items = sorted((float(k), float(v)) for k, v in obj.items())
            a = np.asarray(items)
            return a[:, 0], a[:, 1]
        except Exception:  # noqa: BLE001
            return None
    for k in _X_KEYS:
        if k in obj and isinstance(obj[k], list) and len(obj[k]) == len(y):
            return np.asarray(obj[k], dtype=float), y
    for k in _EDGE_KEYS:
        if k in obj and isinstance(obj[k], list) and len(obj[k]) == len(y) + 1:
            e = np.asarray(obj[k], dtype=float)
            return 0.5 * (e[1:] + e[:-1]), y
    return np.arange(len(y), dtype=float), y


_COMPONENTS = {"highlight": ("highlight", "hi", "specular"),
               "shadow": ("shadow", "sh", "shadows"),
               "self_shadow": ("self_shadow",), "cast_shadow": ("cast_shadow",),
               "total": ("total", "all")}


def ie_components(payload) -> dict:
    """``{component: scalar}`` and ``{component + "_by_zenith": (x, y)}`` from an
    ie_decomposition payload (tolerant to naming)."""
    obj = parse_json(payload)
    out = {}
    if not isinstance(obj, dict):
        return out
    if isinstance(obj.get("part"), list) and (isinstance(obj.get("ie_rel"), list)
                                              or isinstance(obj.get("ie"), list)):
        return _ie_frame_components(obj)
    flat = dict(obj)
    for k in ("ie", "scalars", "summary", "mean"):
        if isinstance(obj.get(k), dict):
            flat.update(obj[k])
    for comp, names in _COMPONENTS.items():
        for nm in names:
            for key in (nm, f"ie_{nm}", f"{nm}_ie", f"{nm}_mean"):
                v = flat.get(key)
                if isinstance(v, (int, float)) and comp not in out:
                    out[comp] = float(v)
    x = None
    for k in _X_KEYS:
        if isinstance(flat.get(k), list):
            x = np.asarray(flat[k], dtype=float)
            break
    if x is None:
        for k in _EDGE_KEYS:
            if isinstance(flat.get(k), list):
                e = np.asarray(flat[k], dtype=float)
                x = 0.5 * (e[1:] + e[:-1])
                break
    by = flat.get("by_zenith") if isinstance(flat.get("by_zenith"), dict) else flat
    if isinstance(by, dict):
        bx = x
        for k in _X_KEYS:
            if isinstance(by.get(k), list):
                bx = np.asarray(by[k], dtype=float)
        for comp, names in _COMPONENTS.items():
            for nm in names:
                for key in (nm, f"ie_{nm}", f"{nm}_by_zenith"):
                    v = by.get(key)
                    if isinstance(v, list) and len(v) > 1 and bx is not None and len(v) == len(bx):
                        out.setdefault(comp + "_by_zenith", (bx, np.asarray(v, dtype=float)))
    return out


def _ie_frame_components(obj) -> dict:
    """psbench.analysis.ie_decomposition's DataFrame (as a dict of lists): columns part
    (highlight, self_shadow, cast_shadow, total), ie, ie_rel (% of the images' dynamic
    range) and, when binned by surface zenith, zenith. ``shadow`` = self + cast."""
    df = pd.DataFrame(obj)
    val = "ie_rel" if "ie_rel" in df and df["ie_rel"].notna().any() else "ie"
    out = {}
    if "zenith" in df and df["zenith"].notna().any():
        for part, g in df.groupby("part"):
            m = g.groupby("zenith")[val].mean()
            out[f"{part}_by_zenith"] = (m.index.to_numpy(float), m.to_numpy(float))
        if "self_shadow_by_zenith" in out and "cast_shadow_by_zenith" in out:
            x, a = out["self_shadow_by_zenith"]
            _, b = out["cast_shadow_by_zenith"]
            both = np.isnan(a) & np.isnan(b)
            out["shadow_by_zenith"] = (x, np.where(both, np.nan,
                                                   np.nan_to_num(a) + np.nan_to_num(b)))
        for part in list(out):
            x, y = out[part]
            ok = np.isfinite(y)
            out[part] = (x[ok], y[ok])
    else:
        m = df.groupby("part")[val].mean()
        out.update({str(k): float(v) for k, v in m.items()})
        if "self_shadow" in out and "cast_shadow" in out:
            out["shadow"] = out["self_shadow"] + out["cast_shadow"]
    return out


# ----------------------------------------------------------------------------- reading

def lookup(agg: pd.DataFrame, part: str, row: str, column: str):
    """One aggregate value or NaN."""
    if agg is None or agg.empty:
        return float("nan")
    m = agg[(agg["part"] == part) & (agg["row"] == row) & (agg["column"] == column)]
    return float(m["value"].iloc[0]) if len(m) else float("nan")


def series(agg: pd.DataFrame, part: str, row: str) -> pd.Series:
    """Values of one (part, row) indexed by numeric column (sorted); non-numeric dropped."""
    if agg is None or agg.empty:
        return pd.Series(dtype=float)
    m = agg[(agg["part"] == part) & (agg["row"] == row)]
    x = pd.to_numeric(m["column"], errors="coerce")
    s = pd.Series(m["value"].to_numpy(), index=x.to_numpy()).dropna()
    s = s[~pd.isna(s.index)]
    return s.sort_index()
