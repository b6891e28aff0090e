"""Matplotlib (Agg) figures drawn from the aggregates: helpers and the dispatcher.

An experiment module draws its own figures in ``figures(agg) -> [(stem, Figure)]`` (see
:mod:`psbench.experiments`) with the helpers here; it imports this module inside that
function, so running an experiment's grid never imports matplotlib. Where the thesis
quotes numbers for a figure they are drawn as black crosses. :func:`figures` dispatches
and never raises (a failing plot is reported as a message).
"""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .aggregates import series  # noqa: E402

__all__ = ["DPI", "plt", "new_figure", "row_names", "line", "finish", "figures"]

DPI = 80


def new_figure(w=5.0, h=3.4, ncols=1):
    """``(figure, axes)``: one row of ``ncols`` axes, each ``w`` x ``h`` inches."""
    fig, axes = plt.subplots(1, ncols, figsize=(w * ncols, h), squeeze=False)
    return fig, axes[0]


def row_names(agg, part=""):
    """Row labels of one part of an aggregate, in first-seen order."""
    if agg is None or agg.empty:
        return []
    return list(dict.fromkeys(agg[agg["part"] == part]["row"]))


def line(ax, agg, part, row, label=None, **kw):
    """Plot one (part, row) of an aggregate against its numeric columns; returns the series."""
    s = series(agg, part, row)
    if len(s):
        ax.plot(s.index, s.to_numpy(), marker="o", ms=3, label=label or row, **kw)
    return s


def finish(ax, xlabel, ylabel, title=None, legend=True):
    """Axis labels, title, grid and (when there are labelled lines) a legend."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    if legend and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)


def figures(experiment, agg):
    """``[(stem, Figure)]`` of one registered experiment, and a list of error messages."""
    from .tables import experiment_module

    fn = getattr(experiment_module(experiment), "figures", None)
    if fn is None or agg is None or agg.empty:
        return [], []
    try:
        return list(fn(agg) or []), []
    except Exception as exc:  # noqa: BLE001
        plt.close("all")
        return [], [f"{experiment}: figure failed: {type(exc).__name__}: {exc}"]
