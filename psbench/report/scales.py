"""Which scales a store holds, and the rule that keeps a report from being destroyed.

Each experiment runs at a ``full`` and a ``ci`` scale (its grid YAML). A report folder
holds one scale: the full-scale report in ``<out>/`` and the ci-scale one in
``<out>/ci/`` (:func:`folder`). ``psbench-report`` reports the scales the store holds
(:func:`held`) and never replaces a report that has data with one that has less:

- a folder holding a report of another scale is not overwritten;
- a page that reports runs is not replaced by a "NO DATA" page: when the store lacks
  that experiment at that scale, the page is kept as it is (:func:`kept`, listed apart
  on the index) unless ``force``; a store with no run at that scale at all is refused.

Every build leaves ``report.json`` (scale, runs and verdict counts per experiment) that
:func:`existing` reads back; reports written before it existed are recognized from their
pages.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import pandas as pd

from psbench._shared.checks import PsbenchError

from . import tables as T

__all__ = ["SCALES", "MANIFEST", "ReportRefused", "folder", "held", "existing", "check",
           "manifest", "kept"]

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
            exps = doc.get("experiments") or {}
            with_data = {n for n, e in exps.items() if int(e.get("runs", 0)) > 0}
            return {"scale": doc.get("scale"), "with_data": with_data,
                    "runs": sum(int(e.get("runs", 0)) for e in exps.values())}
        except (ValueError, TypeError, AttributeError):
            pass
    index = d / "index.md"
    if not index.is_file():
        return None
    m = re.search(r"\(scale: (\w+)\)", index.read_text(errors="replace")[:2000])
    with_data, runs = set(), 0
    for page in d.glob("*.md"):
        if page.stem in ("index", "panels"):
            continue
        text = page.read_text(errors="replace")
        if "NO DATA" in text:
            continue
        r = re.search(r"Runs: (\d+) ok", text)
        if r and int(r.group(1)) > 0:
            with_data.add(page.stem)
            runs += int(r.group(1))
    return {"scale": m.group(1) if m else None, "with_data": with_data, "runs": runs}


def _runs_by_experiment(folder_) -> dict:
    """``{experiment: ok runs}`` of the report in ``folder_`` (from its manifest)."""
    try:
        exps = json.loads((Path(folder_) / MANIFEST).read_text()).get("experiments") or {}
        return {n: int(e.get("runs", 0)) for n, e in exps.items()}
    except (OSError, ValueError, TypeError, AttributeError):
        return {}


_TOTALS = re.compile(r"\*\*\d+ claims?: (\d+) SUPPORTED · (\d+) NOT SUPPORTED · "
                     r"(\d+) INCONCLUSIVE")
_VERDICT_LINE = re.compile(r"^(?:- \*\*|\| )(SUPPORTED|NOT SUPPORTED|INCONCLUSIVE)(?:\*\*| \|)",
                           re.MULTILINE)


def _page_entry(page: Path) -> dict:
    """Runs and verdict counts of a page written without a manifest entry."""
    text = page.read_text(errors="replace") if page.is_file() else ""
    r, t = re.search(r"Runs: (\d+) ok", text), _TOTALS.search(text)
    if t:
        counts = [int(x) for x in t.groups()]
    else:                         # older pages: one "- **STATUS** — claim" line per verdict
        found = _VERDICT_LINE.findall(text)
        counts = [found.count(k) for k in ("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE")]
    return {"runs": int(r.group(1)) if r else 0,
            **dict(zip(("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE"), counts))}


def kept(folder_, runs: dict) -> dict:
    """``{experiment: entry}``: pages of the report in ``folder_`` that hold runs the store
    lacks (``runs[experiment] == 0``); the build leaves them as they are. ``entry`` holds
    their runs and verdict counts (from the manifest, else read from the page) and
    ``kept: True``."""
    old = existing(folder_)
    if not old:
        return {}
    try:
        exps = json.loads((Path(folder_) / MANIFEST).read_text()).get("experiments") or {}
    except (OSError, ValueError, TypeError, AttributeError):
        exps = {}
    return {n: {**(exps.get(n) or _page_entry(Path(folder_) / f"{n}.md")), "kept": True}
            for n in sorted(old["with_data"]) if n in runs and runs[n] == 0
            and (Path(folder_) / f"{n}.md").is_file()}


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


def manifest(scale, results, summaries, generated, kept_=None) -> str:
    """Text of ``report.json``: the scale and, per experiment, runs and verdict counts
    (``kept_``: entries of the pages left from an earlier build, :func:`kept`)."""
    exps = {s["experiment"]: {"runs": int(s["ok"]), "failed": int(s["failed"]),
                              "SUPPORTED": int(s["supported"]),
                              "NOT SUPPORTED": int(s["not_supported"]),
                              "INCONCLUSIVE": int(s["inconclusive"]),
                              "expected": s.get("expected")} for s in summaries}
    for s in summaries:          # verdicts of an incomplete grid (absent when complete)
        if s.get("provisional"):
            exps[s["experiment"]]["PROVISIONAL"] = int(s["provisional"])
    exps.update(kept_ or {})
    counted = [s["experiment"] for s in summaries if s.get("in_totals", True)]
    tot = {k: sum(exps[n][k] for n in counted)
           for k in ("SUPPORTED", "NOT SUPPORTED", "INCONCLUSIVE")}
    if any(exps[n].get("PROVISIONAL") for n in counted):
        tot["PROVISIONAL"] = sum(exps[n].get("PROVISIONAL", 0) for n in counted)
    return json.dumps({"scale": scale, "store": str(results), "generated": generated,
                       "verdicts": tot, "in_totals": counted, "experiments": exps},
                      indent=1) + "\n"
