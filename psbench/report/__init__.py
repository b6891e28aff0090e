"""Thesis reports from the results store: tables vs thesis, verdicts, figures, CI gate.

The experiments themselves live in :mod:`psbench.experiments` (one module + grid YAML
each, found through :mod:`psbench.registry`); this package is the machinery that reports
them and the library their modules use:

- :mod:`.aggregates` helpers to build and read the long-format aggregates;
- :mod:`.verdicts` the Verdict type and the shared rules (margins, no data);
- :mod:`.figures` plotting helpers and house style; :mod:`.panels` image panels;
- :mod:`.tables` store rows -> each experiment's aggregate -> comparison with the thesis;
- :mod:`.present` units, precision and layout of the comparison tables;
- :mod:`.pages` the blocks of each page and of the index; :mod:`.html` Markdown + HTML;
- :mod:`.scales` which scales a store holds; the rule that keeps reports from being
  replaced by emptier ones;
- :mod:`.cli` ``psbench-report``; :mod:`.gate` ``python -m psbench.report.gate check|update``.
"""
from __future__ import annotations

__all__ = ["build"]


def build(results="results", out="reports", scale="full", panels=False, force=False):
    """Rebuild the ``scale`` report in ``out`` from the store at ``results`` (see
    :func:`psbench.report.cli.build`; refuses to replace a report holding data the store
    lacks unless ``force``)."""
    from .cli import build as _build

    return _build(results, out, scale, panels=panels, force=force)
