"""Which scales a store holds, and the rule that keeps a report from being destroyed.

Each experiment runs at a ``full`` and a ``ci`` scale (its grid YAML). A report folder
holds one scale: the full-scale report in ``<out>/`` and the ci-scale one in
``<out>/ci/`` (:func:`folder`). ``psbench-report`` reports the scales the store holds
(:func:`held`) and never replaces a report that has data with one that has less:

- a folder holding a report of another scale is not overwritten;
- a page that reports runs is not replaced by a "NO DATA" page: when the store lacks
  that experiment at that scale, the page is kept as it is (:func:`kept`; the index and
  the totals still count it, marked kept) unless ``force``; a store with no run at that
  scale at all is refused.

Every build leaves ``report.json`` (scale, runs, image size and verdict counts per
experiment, kept pages included) that :func:`existing` reads back; reports written
before it existed are recognized from their pages.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd

from psbench._shared.checks import PsbenchError

from . import tables as T
from .pages import VERDICTS_HEADING, in_totals

__all__ = ["SCALES", "MANIFEST", "ReportRefused", "folder", "held", "existing", "check",
           "manifest", "kept", "page_verdicts", "kept_verdicts"]

SCALES = ("full", "ci")
MANIFEST = "report.json"


class ReportRefused(PsbenchError):
    """psbench-report would replace a report holding data with an emptier one."""


def folder(out, scale) -> Path:
    """Folder of the ``scale`` report under the report root ``out``."""
    return Path(out) if scale == "full" else Path(out) / scale


def _other(scale):
    return [s for s in SCALES if s != scale]


def held(df: pd.DataFrame, results=None, names=None) -> dict[str, list[str]]:
    """``{scale: [experiment, ...]}``: experiments with ok rows that belong to that scale
    only (a run shared by both scales, e.g. table2_1's, decides nothing). A row belongs
    to a scale when its run_id is in the scale's current grid; when no row of an
    experiment matches its grid (paths expanded elsewhere), the image size decides."""
    out = {s: [] for s in SCALES}
    if df is None or df.empty:
        return out
    for name in (names if names is not None else T.names()):
        ids = {s: T.expected_run_ids(name, s, results) or set() for s in SCALES}
        sizes = {s: T.scale_size(name, s, results) for s in SCALES}
        for s in SCALES:
            rows = T.select(df, name, s, status="ok", results=results)
            if rows.empty:
                continue
            mine = rows["run_id"].isin(ids[s])
            if mine.any():
                others = set().union(*(ids[o] for o in _other(s)))
                if (mine & ~rows["run_id"].isin(others)).any():
                    out[s].append(name)
            elif sizes[s] is not None and all(sizes[o] != sizes[s] for o in _other(s)):
                out[s].append(name)
    return out


def existing(folder_) -> dict | None:
    """What the report in ``folder_`` holds: ``{"scale", "with_data": set of experiments
    with runs, "runs"}``; None when there is no report."""
    d = Path(folder_)
    man = d / MANIFEST
    if man.is_file():
        try:
            doc = json.loads(man.read_text())
            runs = {n: int(e.get("runs", 0)) for n, e in (doc.get("experiments") or {}).items()}
            # a page written after the manifest (one experiment built alone) may hold runs
            runs.update({n: _page_runs(d / f"{n}.md") for n, k in runs.items() if k == 0})
            return {"scale": doc.get("scale"), "with_data": {n for n, k in runs.items() if k},
                    "runs": sum(runs.values())}
        except (ValueError, TypeError, AttributeError):
            pass
    index = d / "index.md"
    if not index.is_file():
        return None
    m = re.search(r"\(scale: (\w+)\)", index.read_text(errors="replace")[:2000])
    runs = {p.stem: _page_runs(p) for p in d.glob("*.md") if p.stem not in ("index", "panels")}
    return {"scale": m.group(1) if m else None, "with_data": {n for n, k in runs.items() if k},
            "runs": sum(runs.values())}


def _page_runs(page: Path) -> int:
    """Ok runs an experiment page reports (0: no page, or a NO DATA page)."""
    text = page.read_text(errors="replace") if page.is_file() else ""
    r = re.search(r"Runs: (\d+) ok", text)
    return 0 if "NO DATA" in text or not r else int(r.group(1))


def _runs_by_experiment(folder_) -> dict:
    """``{experiment: ok runs}`` of the report in ``folder_`` (from its manifest)."""
    try:
        exps = json.loads((Path(folder_) / MANIFEST).read_text()).get("experiments") or {}
        return {n: int(e.get("runs", 0)) for n, e in exps.items()}
    except (OSError, ValueError, TypeError, AttributeError):
        return {}


_TOTALS = re.compile(r"\*\*\d+ claims?: (\d+) SUPPORTED · (\d+) NOT SUPPORTED · "
                     r"(\d+) INCONCLUSIVE(?: · (\d+) PROVISIONAL)?")
_INCOMPLETE = re.compile(r"INCOMPLETE GRID: \d+ of (\d+) runs present")
_VERDICT_LINE = re.compile(r"^(?:- \*\*|\| )(SUPPORTED|NOT SUPPORTED|INCONCLUSIVE)(?:\*\*| \|)",
                           re.MULTILINE)


#: the page's second paragraph, e.g. "Experiment `x`, scale `full` (image size 512 x 512; ..."
_SIZE = re.compile(r"^Experiment `[^`]+`, scale `\w+` \(image size (\d+) x \d+", re.MULTILINE)


def _page_size(page: Path):
    """Image size stated by an experiment page (None: no page, or no images)."""
    text = page.read_text(errors="replace")[:20000] if page.is_file() else ""
    m = _SIZE.search(text)
    return int(m.group(1)) if m else None


def _page_entry(page: Path) -> dict:
    """Runs and verdict counts of a page written without a manifest entry (with
    ``PROVISIONAL`` and ``expected`` when the page's grid is incomplete)."""
    text = page.read_text(errors="replace") if page.is_file() else ""
    r, t = re.search(r"Runs: (\d+) ok", text), _TOTALS.search(text)
    if t:
        counts = [int(x) for x in t.groups()[:3]]
    else:                         # older pages: one "- **STATUS** — claim" line per verdict
        found = _VERDICT_LINE.findall(text)
        counts = [found.count(k) for k in ("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE")]
    out = {"runs": int(r.group(1)) if r else 0,
           **dict(zip(("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE"), counts))}
    if t and t.group(4):
        out["PROVISIONAL"] = int(t.group(4))
    if i := _INCOMPLETE.search(text):
        out["expected"] = int(i.group(1))
    return out


_CELL = re.compile(r"(?<!\\)\|")
_QUOTE = " (thesis, "


def page_verdicts(page, experiment) -> list:
    """The thesis verdicts an experiment page states (its table under "Verdicts on the
    thesis's conclusions", read from the page's Markdown) as
    :class:`~psbench.report.verdicts.Verdict`: a kept page's claims for the index's Key
    findings and All verdicts. ``[]`` when the page has no such table."""
    from .verdicts import Verdict

    text = Path(page).read_text(errors="replace") if Path(page).is_file() else ""
    _, sep, rest = text.partition(f"## {VERDICTS_HEADING}")
    out = []
    if not sep:
        return out
    for line in rest.splitlines():
        if line.startswith("#"):                       # the next section
            break
        if not line.startswith("| ") or line.startswith("| status |"):
            continue
        cells = [c.strip().replace("\\|", "|") for c in _CELL.split(line)[1:-1]]
        if len(cells) != 3:
            continue
        status, claim, detail = cells
        quote = ""
        cut = claim.rfind(_QUOTE)
        if cut > 0 and claim.endswith(")"):            # "claim (thesis, <quote>)"
            claim, quote = claim[:cut], claim[cut + len(_QUOTE):-1]
        out.append(Verdict(experiment, claim, status, detail, quote))
    return out


def kept_verdicts(folder_, experiment, entry) -> list:
    """A kept page's thesis verdicts: those its build stored in ``report.json`` (the
    entry's ``claims``), else read from the page (:func:`page_verdicts`: a manifest
    written before the claims were stored)."""
    from .verdicts import Verdict

    claims = entry.get("claims")
    if isinstance(claims, list) and all(isinstance(c, dict) for c in claims):
        return [Verdict(experiment, str(c.get("claim", "")), str(c.get("status", "")),
                        str(c.get("detail", "")), str(c.get("quote", ""))) for c in claims]
    return page_verdicts(Path(folder_) / f"{experiment}.md", experiment)


def kept(folder_, runs: dict) -> dict:
    """Pages of an earlier build that this store cannot rebuild.

    Parameters
    ----------
    folder_ : path
        Folder of the report.
    runs : dict
        ``{experiment: ok runs}`` of the store at this scale; a page is kept when its
        experiment is a key with 0 runs and the page holds runs.

    Returns
    -------
    dict
        ``{experiment: entry}`` in the order of ``runs``; ``entry`` holds the page's runs
        and verdict counts (its manifest entry, else read from the page), ``size`` (the
        manifest's, else the page's stated image size; None without images) and
        ``kept: True``.
    """
    old = existing(folder_)
    if not old:
        return {}
    try:
        exps = json.loads((Path(folder_) / MANIFEST).read_text()).get("experiments") or {}
    except (OSError, ValueError, TypeError, AttributeError):
        exps = {}
    out = {}
    for n in runs:
        page = Path(folder_) / f"{n}.md"
        if runs[n] != 0 or n not in old["with_data"] or not page.is_file():
            continue
        stored = exps.get(n) or {}
        # a manifest entry without runs predates the page (one experiment built alone)
        entry = {**(stored if int(stored.get("runs", 0)) else _page_entry(page)), "kept": True}
        if entry.get("size") is None:         # older manifests do not store it
            entry["size"] = _page_size(page)
        out[n] = entry
    return out


def _names(xs, k=4):
    xs = sorted(xs)
    return ", ".join(xs[:k]) + (f" and {len(xs) - k} more" if len(xs) > k else "")


def check(folder_, scale, runs: dict, results, force=False) -> None:
    """Raise :class:`ReportRefused` (one line) when writing the ``scale`` report with
    ``runs`` (``{experiment: ok runs}``) into ``folder_`` would destroy data."""
    if force:
        return
    old = existing(folder_)
    if not old or not old["with_data"]:
        return
    where = str(folder_).rstrip("/") + "/"
    if old["scale"] and old["scale"] != scale:
        raise ReportRefused(
            f"psbench-report: refusing to write the {scale}-scale report into {where}: it "
            f"holds a {old['scale']}-scale report ({old['runs']} runs); use --out "
            f"another folder or --force")
    lost = [n for n in old["with_data"] if n in runs and runs[n] == 0]
    if lost and not any(runs.values()):
        raise ReportRefused(
            f"psbench-report: refusing to overwrite {where} ({old['scale'] or scale}-scale "
            f"report, {old['runs']} runs): the store {results} holds no {scale}-scale runs; "
            f"run `psbench +experiment=NAME scale={scale}` first, or --force")
    fewer = {n: (k, runs[n]) for n, k in _runs_by_experiment(folder_).items()
             if n in runs and 0 < runs[n] < k}
    if fewer:                    # e.g. a corrupt store file: never rebuild from fewer rows
        n, (k, now) = sorted(fewer.items())[0]
        raise ReportRefused(
            f"psbench-report: refusing to overwrite {where}: the store {results} holds fewer "
            f"runs than its pages report for {len(fewer)} experiment(s) ({n}: {now} of {k}; "
            f"see the store warnings above, `psbench-results verify`); the old pages are "
            f"kept: rerun the experiments to resume, or --force")


def manifest(scale, results, summaries, generated, kept_=None, order=None,
             verdicts=None) -> str:
    """Text of ``report.json``.

    Parameters
    ----------
    scale, results, generated : str
        The report's scale, its store (as shown) and the build time.
    summaries : list of dict
        The built experiments' summaries (``psbench.report.cli``).
    kept_ : dict, optional
        Entries of the pages left from an earlier build (:func:`kept`), stored as they
        are; they count in the totals like built pages.
    order : list of str, optional
        Experiment order (default: the registered order, :func:`tables.names`).
    verdicts : dict, optional
        ``{experiment: [Verdict]}``: the thesis claims each page states, stored as the
        entry's ``claims`` (claim, status, detail, quote) so that a later build that
        keeps the page lists them as they were (:func:`kept_verdicts`).

    Returns
    -------
    str
        JSON: scale, store, time, verdict totals, the experiments in them, and per
        experiment runs, image size, verdict counts and claims.
    """
    exps = {s["experiment"]: {"runs": int(s["ok"]), "failed": int(s["failed"]),
                              "SUPPORTED": int(s["supported"]),
                              "NOT SUPPORTED": int(s["not_supported"]),
                              "INCONCLUSIVE": int(s["inconclusive"]),
                              "expected": s.get("expected"),
                              "size": int(s["size"]) if s.get("size") else None}
            for s in summaries}
    for s in summaries:          # verdicts of an incomplete grid (absent when complete)
        if s.get("provisional"):
            exps[s["experiment"]]["PROVISIONAL"] = int(s["provisional"])
    exps.update({n: dict(e) for n, e in (kept_ or {}).items()})
    for n, vs in (verdicts or {}).items():
        if n in exps:
            exps[n]["claims"] = [{"claim": v.claim, "status": v.status, "detail": v.detail,
                                  "quote": v.quote} for v in vs]
    pos = {n: i for i, n in enumerate(order if order is not None else T.names())}
    exps = dict(sorted(exps.items(), key=lambda kv: pos.get(kv[0], len(pos))))
    built = {s["experiment"]: s.get("in_totals", True) for s in summaries}
    counted = [n for n in exps if (built[n] if n in built else in_totals(n))]
    tot = {k: sum(int(exps[n].get(k, 0)) for n in counted)
           for k in ("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE")}
    if any(exps[n].get("PROVISIONAL") for n in counted):
        tot["PROVISIONAL"] = sum(int(exps[n].get("PROVISIONAL", 0)) for n in counted)
    return json.dumps({"scale": scale, "store": str(results), "generated": generated,
                       "verdicts": tot, "in_totals": counted, "experiments": exps},
                      indent=1) + "\n"
