"""Thesis reports from the results store: tables vs thesis, verdicts, figures, CI gate.

The experiments themselves live in :mod:`psbench.experiments` (one module + grid YAML
each, found through :mod:`psbench.registry`); this package is the machinery that reports
them and the library their modules use:

- :mod:`.aggregates` helpers to build and read the long-format aggregates;
- :mod:`.verdicts` the Verdict type and the shared rules (margins, no data);
- :mod:`.figures` plotting helpers; :mod:`.panels` image panels; :mod:`.html` pages;
- :mod:`.tables` store rows -> each experiment's aggregate -> comparison with the thesis;
- :mod:`.cli` ``psbench-report``; :mod:`.gate` ``python -m psbench.report.gate check|update``.
"""
from __future__ import annotations

__all__ = ["build"]


def build(results="results", out="reports", scale="full", panels=False):
    """Rebuild ``out`` from the store at ``results`` (see :func:`psbench.report.cli.build`)."""
    from .cli import build as _build

    return _build(results, out, scale, panels=panels)
