"""Thesis reports from the results store: tables vs thesis, verdicts, figures, CI gate.

- :mod:`.thesis_values` every thesis table's numbers, keyed table/part/row/column;
- :mod:`.tables` aggregation of store rows into those keys (one long frame per experiment);
- :mod:`.verdicts` one SUPPORTED / NOT SUPPORTED / INCONCLUSIVE line per conclusion;
- :mod:`.figures`, :mod:`.panels`, :mod:`.html` figures, image panels, Markdown/HTML pages;
- :mod:`.cli` ``psbench-report``; :mod:`.gate` ``python -m psbench.report.gate check|update``.
"""
from __future__ import annotations

__all__ = ["build"]


def build(results="results", out="reports", scale="full", panels=False):
    """Rebuild ``out`` from the store at ``results`` (see :func:`psbench.report.cli.build`)."""
    from .cli import build as _build

    return _build(results, out, scale, panels=panels)
