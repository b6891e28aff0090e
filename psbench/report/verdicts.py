"""Verdicts on the thesis's qualitative conclusions: the type, the rules, the dispatcher.

Every experiment module decides its own claims in ``verdicts(agg, rows)`` (see
:mod:`psbench.experiments`) with the helpers here, so that all experiments share one set
of rules:

- a claim whose data are missing is INCONCLUSIVE ("no data", :func:`nodata`);
- a comparison whose two sides differ by less than a stated margin (:data:`NE_MARGIN`
  = 0.1 deg of NE unless the claim states another) is INCONCLUSIVE rather than decided
  by noise (``verdict(..., undecided=True)``, :func:`lowest`);
- the ``detail`` of every verdict holds the numbers it was decided on.

:func:`verdicts` runs one experiment's checks and never raises: a failing check becomes
one INCONCLUSIVE verdict naming the error.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["SUPPORTED", "NOT_SUPPORTED", "INCONCLUSIVE", "NE_MARGIN", "Verdict", "verdict",
           "nodata", "lowest", "rank", "part_values", "slope", "ok", "num", "verdicts"]

SUPPORTED, NOT_SUPPORTED, INCONCLUSIVE = "SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE"
NE_MARGIN = 0.1  # degrees: NE differences below this are not decided


@dataclass
class Verdict:
    """One decided claim.

    Attributes
    ----------
    experiment : str
        Experiment name (filled in by :func:`verdicts` when a check leaves it empty).
    claim : str
        The thesis's conclusion, in one line.
    status : {"SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE"}
    detail : str
        psbench's numbers (and the thesis's) the status was decided on.
    """

    experiment: str
    claim: str
    status: str
    detail: str

    def as_dict(self):
        return {"experiment": self.experiment, "claim": self.claim, "status": self.status,
                "detail": self.detail}


def ok(x) -> bool:
    """``x`` is a number (not None, not NaN)."""
    return x is not None and not (isinstance(x, float) and math.isnan(x))


def num(x, nd=2) -> str:
    """``x`` with ``nd`` decimals, ``"n/a"`` when missing."""
    return "n/a" if not ok(x) else f"{x:.{nd}f}"


def verdict(claim, cond, detail, undecided=False) -> Verdict:
    """SUPPORTED if ``cond``, NOT SUPPORTED if not; INCONCLUSIVE when ``cond`` is None (no
    data) or ``undecided`` (e.g. a gap below its margin)."""
    if cond is None:
        return Verdict("", claim, INCONCLUSIVE, detail or "no data")
    if undecided:
        return Verdict("", claim, INCONCLUSIVE, detail)
    return Verdict("", claim, SUPPORTED if cond else NOT_SUPPORTED, detail)


def nodata(claim) -> Verdict:
    """INCONCLUSIVE: the store holds nothing to decide ``claim`` on."""
    return Verdict("", claim, INCONCLUSIVE, "no data in the store for this claim")


def part_values(agg, part, column) -> dict:
    """``{row: value}`` of one part and column of an aggregate (missing values dropped)."""
    if agg is None or agg.empty:
        return {}
    m = agg[(agg["part"] == part) & (agg["column"] == column)]
    return {r: float(v) for r, v in zip(m["row"], m["value"]) if ok(float(v))}


def lowest(claim, values: dict, who: str, margin=NE_MARGIN, unit="deg") -> Verdict:
    """``who`` has the lowest value of ``values``; INCONCLUSIVE when it misses the best
    by less than ``margin``."""
    if not values or who not in values:
        return nodata(claim)
    best = min(values, key=values.get)
    ranked = sorted(values.items(), key=lambda kv: kv[1])
    top = ", ".join(f"{k} {num(v)}" for k, v in ranked[:4])
    if best == who:
        return verdict(claim, True, f"{who} lowest ({num(values[who])} {unit}); ranking: {top}")
    gap = values[who] - values[best]
    return verdict(claim, False, f"{who} {num(values[who])} vs best {best} {num(values[best])} "
                   f"(gap {num(gap)} {unit}{' < margin' if gap < margin else ''}); ranking: "
                   f"{top}", undecided=gap < margin)


def rank(values: dict, who: str):
    """1-based rank of ``who`` in ascending ``values`` (None if absent)."""
    ranked = sorted(values, key=values.get)
    return ranked.index(who) + 1 if who in ranked else None


def slope(s: pd.Series) -> float:
    """Least-squares slope of a series over its numeric index (NaN with < 2 points)."""
    if len(s) < 2:
        return float("nan")
    x = np.asarray(s.index, float)
    return float(np.polyfit(x, s.to_numpy(), 1)[0])


def verdicts(experiment: str, agg: pd.DataFrame, rows: pd.DataFrame | None = None):
    """The verdict list of one registered experiment (never raises: a failing check is one
    INCONCLUSIVE verdict)."""
    from .tables import experiment_module

    fn = getattr(experiment_module(experiment), "verdicts", None)
    if fn is None:
        return []
    try:
        out = [v for v in fn(agg, rows) if v is not None]
    except Exception as exc:  # noqa: BLE001 - a broken check must not break the report
        return [Verdict(experiment, "(verdict computation)", INCONCLUSIVE,
                        f"check failed: {type(exc).__name__}: {exc}")]
    return [v if v.experiment else dataclasses.replace(v, experiment=experiment) for v in out]
