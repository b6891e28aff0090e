"""Ranking a sweep's rows and finding its axes (shared by the sweep summary and the
comparison sheet)."""
from __future__ import annotations

import json
import math

__all__ = ["rank", "varying"]


def _num(v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def rank(rows):
    """Rows sorted best first: ok runs by mean NE (runs without NE by IE %), failed last."""
    def key(r):
        ok = r.get("status") == "ok"
        ne, ie = _num(r.get("ne_mean")), _num(r.get("ie_rel"))
        return (not ok, ne is None, ne if ne is not None else (ie if ie is not None else 1e300))
    return sorted(rows, key=key)


_SKIP = {"run_id", "sweep", "experiment", "kind", "config", "n_images", "size"}


def varying(rows) -> list[str]:
    """Run parameters whose values differ between ``rows`` (the sweep's axes)."""
    from .spec import param_names

    out = []
    for name in param_names():
        if name in _SKIP:
            continue
        vals = {json.dumps(r.get(name), default=str, sort_keys=True) for r in rows}
        if len(vals) > 1:
            out.append(name)
    return out or ["mask", "method"]
