"""Verdicts on the thesis's qualitative conclusions: the type, the rules, the dispatcher.

Every experiment module decides its own claims in ``verdicts(agg, rows)`` (see
:mod:`psbench.experiments`) with the helpers here, so that all experiments share one set
of rules:

- a claim whose data are missing is INCONCLUSIVE ("no data", :func:`nodata`);
- a comparison is decided by a *gap* (how far the claim holds, in the claim's unit) and
  a *margin*: SUPPORTED when gap >= margin, NOT SUPPORTED when gap <= -margin,
  INCONCLUSIVE in between (:func:`decide`, :func:`lowest`). The margin is

  * :data:`NE_MARGIN` (0.1 deg of NE) unless the claim states another
    (:data:`QF_MARGIN` for quality factors),
  * but no tighter than the thesis's own evidence: when the thesis decided the same
    claim on a smaller gap (e.g. NL-Re 12.27 vs Th 12.29 deg), that gap is the margin
    (:func:`margin_for`);
  * and never below the claim's seed-to-seed spread: when the rows hold several seeds
    (noise realisations), the gap is computed per seed (:func:`by_seed`) and a claim
    decided by a gap smaller than the spread (max - min over seeds) of that gap is
    INCONCLUSIVE;
- the ``detail`` of every verdict holds the numbers it was decided on (and the seed
  spread when measured); ``quote`` holds the thesis's sentence (with its line in
  ``thesis.txt``) the verdict tests.

:func:`verdicts` runs one experiment's checks and never raises: a failing check becomes
one INCONCLUSIVE verdict naming the error.
"""
from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

__all__ = ["SUPPORTED", "NOT_SUPPORTED", "INCONCLUSIVE", "NE_MARGIN", "QF_MARGIN", "Verdict",
           "verdict", "nodata", "lowest", "rank", "part_values", "slope", "ok", "num",
           "verdicts", "margin_for", "spread", "decide", "by_seed", "seed_part_values",
           "quoted", "own", "own_questions", "all_hold", "every", "ranked", "PCT_MARGIN", "plateau",
           "PROVISIONAL", "provisional"]

SUPPORTED, NOT_SUPPORTED, INCONCLUSIVE = "SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE"
#: the status of every verdict decided on an incomplete grid (:func:`provisional`)
PROVISIONAL = "PROVISIONAL"
NE_MARGIN = 0.1  # degrees: NE differences below this are not decided
QF_MARGIN = 0.01  # quality factor (0..1) differences below this are not decided
PCT_MARGIN = 1.0  # percentage points (improvements in %) below this are not decided
_EPS = 1e-9  # a gap equal to its margin (in float arithmetic) counts as reaching it


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
    quote : str
        The thesis's sentence the claim comes from, with its line in ``thesis.txt``
        (``""`` when not given).
    thesis : bool
        True (default) for a thesis conclusion; False for psbench's own question (e.g.
        whether a method the thesis does not have beats its masks), shown apart and not
        counted in the verdict totals.
    """

    experiment: str
    claim: str
    status: str
    detail: str
    quote: str = ""
    thesis: bool = True

    def as_dict(self):
        return {"experiment": self.experiment, "claim": self.claim, "status": self.status,
                "detail": self.detail, "quote": self.quote, "thesis": self.thesis}


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


def own(v: Verdict) -> Verdict:
    """``v`` marked as psbench's own question, not a thesis conclusion."""
    return dataclasses.replace(v, thesis=False)


def own_questions(func):
    """Decorator for an experiment's ``verdicts`` whose claims are all psbench's own
    questions (e.g. benchmarks of methods beyond the thesis)."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        return [own(v) for v in func(*args, **kwargs)]
    return wrapper


def provisional(vs, present: int, expected: int) -> list:
    """``vs`` decided on ``present`` of the ``expected`` runs of a grid: each status
    becomes PROVISIONAL and its detail says what it reads so far, since the missing runs
    may change it."""
    return [dataclasses.replace(v, status=PROVISIONAL,
                                detail=f"{v.status} so far, on {present} of {expected} runs: "
                                       f"{v.detail}") for v in vs]


def quoted(v: Verdict, quote: str) -> Verdict:
    """``v`` with the thesis sentence it tests (``"line N: ..."``)."""
    return dataclasses.replace(v, quote=quote)


def margin_for(margin=NE_MARGIN, thesis_gap=None, spread_=None) -> float:
    """The margin a claim is decided with: ``margin``, lowered to the thesis's own gap
    for the same claim when that is smaller (psbench asks for no more evidence than the
    thesis gave), raised to the seed-to-seed spread of the gap when that is larger."""
    m = float(margin)
    if ok(thesis_gap):
        m = min(m, abs(float(thesis_gap)))
    if ok(spread_):
        m = max(m, float(spread_))
    return m


def spread(values) -> float:
    """max - min of the finite values (NaN with fewer than 2): the seed-to-seed spread."""
    v = np.asarray([x for x in values if ok(x)], dtype=float)
    return float(v.max() - v.min()) if v.size >= 2 else float("nan")


def _seed_note(seed_gaps, unit):
    if seed_gaps is None:
        return ""
    g = [x for x in seed_gaps if ok(x)]
    if len(g) < 2:
        return f"; {len(g)} seed: spread not measured"
    return (f"; per seed, on the runs every seed has: {', '.join(num(x) for x in g)} (spread "
            f"{num(spread(g))} {unit} over {len(g)} seeds)")


def decide(claim, gap, detail, *, margin=NE_MARGIN, thesis_gap=None, seed_gaps=None,
           unit="deg") -> Verdict:
    """Decide a claim from its ``gap`` (> 0: the claim holds by that much).

    SUPPORTED when ``gap >= m``, NOT SUPPORTED when ``gap <= -m``, INCONCLUSIVE in
    between (and when ``gap`` is missing), with ``m = margin_for(margin, thesis_gap,
    spread(seed_gaps))``. ``seed_gaps`` are the same gap computed on each seed's rows
    alone. The detail gets the gap, the margin and the per-seed gaps appended."""
    if not ok(gap):
        return verdict(claim, None, detail)
    sp = spread(seed_gaps) if seed_gaps is not None else None
    m = margin_for(margin, thesis_gap, sp)
    why = f"gap {num(gap)} {unit}, margin {num(m)}"
    if ok(thesis_gap) and abs(thesis_gap) < margin:
        why += f" (the thesis's own gap {num(abs(thesis_gap))})"
    full = f"{detail} [{why}{_seed_note(seed_gaps, unit)}]"
    if gap >= m - _EPS and gap > 0:
        return Verdict("", claim, SUPPORTED, full)
    if gap <= -m + _EPS and gap < 0:
        return Verdict("", claim, NOT_SUPPORTED, full)
    return Verdict("", claim, INCONCLUSIVE, full)


def lowest(claim, values: dict, who: str, margin=NE_MARGIN, unit="deg", *, thesis=None,
           seeds=None, highest=False) -> Verdict:
    """``who`` has the lowest (``highest=True``: the highest) value of ``values``, a
    ``{row: value}`` dict.

    The gap is ``who``'s lead over the best other row (negative: how far it misses the
    best), decided by :func:`decide`. ``thesis`` (``{row: value}`` of the same rows)
    gives the thesis's own lead of ``who`` (the margin is never tighter than it);
    ``seeds`` (``{seed: {row: value}}``) gives the lead per seed (its spread raises the
    margin)."""
    if not values or who not in values or len(values) < 2:
        return nodata(claim)
    sgn = -1.0 if highest else 1.0

    def lead(vals):
        o = {k: v for k, v in vals.items() if k != who and k in values and ok(v)}
        if not o or not ok(vals.get(who)):
            return float("nan"), None
        rival = min(o, key=lambda k: sgn * o[k])
        return sgn * (o[rival] - vals[who]), rival

    gap, rival = lead(values)
    ranked = sorted(values.items(), key=lambda kv: sgn * kv[1])
    top = ", ".join(f"{k} {num(v)}" for k, v in ranked[:4])
    th_gap = lead(thesis)[0] if thesis else None
    seed_gaps = [lead(v)[0] for v in seeds.values()] if seeds else None
    word = "highest" if highest else "lowest"
    if gap > 0:
        detail = f"{who} {word} ({num(values[who])} {unit}, next {rival} {num(values[rival])})"
    else:
        detail = f"{who} {num(values[who])} vs best {rival} {num(values[rival])}"
    return decide(claim, gap, f"{detail}; ranking: {top}", margin=margin, thesis_gap=th_gap,
                  seed_gaps=seed_gaps, unit=unit)


def _kth(vals, who, k):
    """k-th smallest value (1-based) among the rows other than ``who`` (+-inf outside)."""
    o = sorted(v for r, v in vals.items() if r != who and ok(v))
    if k < 1:
        return -math.inf
    return o[k - 1] if k <= len(o) else math.inf


def _rank_gap(vals, who, r, exact):
    if not vals or not ok(vals.get(who)):
        return float("nan")
    v = vals[who]
    below = _kth(vals, who, r) - v            # the r-th other must be worse
    if not exact:
        return below
    return min(below, v - _kth(vals, who, r - 1))   # and the (r-1)-th better


def ranked(claim, values: dict, who: str, r: int, *, exact=True, margin=NE_MARGIN,
           unit="deg", thesis=None, seeds=None) -> Verdict:
    """``who`` ranks ``r``-th lowest in ``values`` (``exact=False``: within the best
    ``r``). The gap is the smaller distance to the neighbours that would change the
    rank, decided by :func:`decide` with the thesis's own gap (``thesis``, ``{row:
    value}``) and the per-seed gaps (``seeds``, ``{seed: {row: value}}``)."""
    if not values or who not in values:
        return nodata(claim)
    gap = _rank_gap(values, who, r, exact)
    th_gap = _rank_gap({k: v for k, v in thesis.items() if k in values}, who, r, exact) \
        if thesis else None
    seed_gaps = [_rank_gap(v, who, r, exact) for v in seeds.values()] if seeds else None
    order = sorted(values, key=values.get)
    detail = (f"{who} ranks {order.index(who) + 1} of {len(values)} ({num(values[who])} {unit});"
              f" ranking: " + ", ".join(f"{k} {num(values[k])}" for k in order))
    return decide(claim, gap if math.isfinite(gap) else (1e9 if gap > 0 else -1e9), detail,
                  margin=margin, thesis_gap=th_gap if th_gap is None or math.isfinite(th_gap)
                  else None, seed_gaps=seed_gaps, unit=unit)


def plateau(s: pd.Series, margin=NE_MARGIN) -> list:
    """The index values of a curve within ``margin`` of its minimum: the optima that a
    sampled curve cannot tell apart (e.g. source zeniths of a flat NE minimum)."""
    s = s.dropna()
    if s.empty:
        return []
    return sorted(float(x) for x in s.index[s <= s.min() + margin + _EPS])


def every(claim, parts, quote="") -> Verdict:
    """A claim made of several sub-claims that must all hold (``parts``: verdicts, e.g.
    one per image count): NOT SUPPORTED when any part is NOT SUPPORTED, SUPPORTED when
    all are SUPPORTED, else INCONCLUSIVE."""
    parts = [p for p in parts if p is not None]
    if not parts:
        return Verdict("", claim, INCONCLUSIVE, "no data in the store for this claim", quote)
    st = [p.status for p in parts]
    status = (NOT_SUPPORTED if NOT_SUPPORTED in st else
              SUPPORTED if all(x == SUPPORTED for x in st) else INCONCLUSIVE)
    return Verdict("", claim, status, "; ".join(f"{p.claim}: {p.status} - {p.detail}"
                                                for p in parts), quote)


#: row columns that identify a run's design point apart from its seed
_DESIGN = ("kind", "surface", "data", "lights", "model", "shadows", "noise", "quantize", "size",
           "mask", "weighted", "method", "weight", "binary", "thresholds", "th_scope",
           "analysis", "args")


def by_seed(rows, aggregate, *, shared=None) -> dict:
    """``{seed: aggregate(that seed's rows)}`` when ``rows`` hold two or more seeds, else
    ``{}`` (one seed: no spread to measure).

    Each seed's rows are restricted to the design points (run parameters other than the
    seed) that every seed has, so the per-seed aggregates average the same runs.
    ``shared`` (bool Series over ``rows``) marks runs whose result does not depend on
    the seed (e.g. noise-free runs of deterministic masks): they count for every seed.
    """
    if rows is None or len(rows) == 0 or "seed" not in rows:
        return {}
    s = pd.to_numeric(rows["seed"], errors="coerce")
    seeds = sorted(s.dropna().unique())
    if len(seeds) < 2:
        return {}
    cols = [c for c in _DESIGN if c in rows]
    key = (rows[cols].map(lambda x: "" if not ok(x) and not isinstance(x, str) else str(x))
           .agg("|".join, axis=1) if cols else pd.Series("", rows.index))
    sh = pd.Series(False, index=rows.index) if shared is None else \
        pd.Series(shared, index=rows.index).fillna(False).astype(bool)
    own = {k: set(key[(s == k) & ~sh]) | set(key[sh]) for k in seeds}
    common = set.intersection(*own.values())
    out = {}
    for k in seeds:
        sel = ((s == k) & ~sh) | (sh & ~key.isin(set(key[(s == k) & ~sh])))
        r = rows[sel & key.isin(common)]
        r = r[~key[r.index].duplicated()]
        if len(r):
            out[int(k)] = aggregate(r)
    return out if len(out) >= 2 else {}


def seed_part_values(per_seed: dict, part, column) -> dict:
    """``{seed: {row: value}}`` of one part and column of per-seed aggregates."""
    return {k: part_values(a, part, column) for k, a in per_seed.items()}


def all_hold(claim, verdicts_by_case: dict, quote="") -> Verdict:
    """One verdict from the same claim decided under several cases (e.g. highlight
    ground-truth definitions): SUPPORTED / NOT SUPPORTED only when every case agrees,
    INCONCLUSIVE when they disagree or a case is missing (``None``)."""
    parts = [f"{case}: {'no data' if v is None else v.status} ({'' if v is None else v.detail})"
             for case, v in verdicts_by_case.items()]
    statuses = {None if v is None else v.status for v in verdicts_by_case.values()}
    status = statuses.pop() if len(statuses) == 1 else INCONCLUSIVE
    if status is None:
        status = INCONCLUSIVE
    return Verdict("", claim, status, "; ".join(parts), quote)


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
