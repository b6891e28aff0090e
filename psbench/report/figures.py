"""Matplotlib (Agg) figures drawn from the aggregates: style, helpers and the dispatcher.

An experiment module draws its own figures in ``figures(agg) -> [(stem, Figure)]``
(``figures(agg, rows=None)`` when it also needs the results rows, e.g. stored maps; see
:mod:`psbench.experiments`) with the helpers here; it imports this module inside that
function, so running an experiment's grid never imports matplotlib. The house style
(:data:`STYLE`) makes every figure at least :data:`MIN_WIDTH` inches x :data:`DPI` (1000
px) wide with labels readable at page width; axis labels carry units; the thesis's
values are drawn with :func:`thesis` (black open diamonds, labelled "thesis" in the
legend). :func:`figures` dispatches and never raises (a failing plot is reported as a
message).
"""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from .aggregates import series  # noqa: E402

__all__ = ["DPI", "MIN_WIDTH", "STYLE", "THESIS_STYLE", "plt", "new_figure", "row_names", "line",
           "thesis", "finish", "figure_legend", "figures"]

DPI = 100
MIN_WIDTH = 10.0     # inches: 1000 px at DPI
STYLE = {"font.size": 13, "axes.titlesize": 14, "axes.labelsize": 14, "xtick.labelsize": 12,
         "ytick.labelsize": 12, "legend.fontsize": 12, "legend.framealpha": 0.9,
         "lines.linewidth": 2.0, "lines.markersize": 6, "axes.grid": True, "grid.alpha": 0.3,
         "figure.dpi": DPI, "savefig.dpi": DPI, "axes.spines.top": False,
         "axes.spines.right": False, "figure.facecolor": "white"}
plt.rcParams.update(STYLE)
THESIS_STYLE = dict(ls="none", marker="D", ms=9, mfc="none", mec="black", mew=1.8, zorder=5)


def new_figure(w=None, h=None, ncols=1, nrows=1):
    """``(figure, axes)``: ``nrows`` x ``ncols`` axes (a flat array when ``nrows`` == 1),
    each ``w`` x ``h`` inches, widened so the figure is at least :data:`MIN_WIDTH` wide."""
    w = max(w or (MIN_WIDTH / ncols if ncols > 1 else MIN_WIDTH), MIN_WIDTH / ncols)
    h = h or (5.2 if ncols == 1 else 4.6)
    fig, axes = plt.subplots(nrows, ncols, figsize=(w * ncols, h * nrows), squeeze=False,
                             layout="constrained")
    return fig, (axes[0] if nrows == 1 else axes)


def row_names(agg, part=""):
    """Row labels of one part of an aggregate, in first-seen order."""
    if agg is None or agg.empty:
        return []
    return list(dict.fromkeys(agg[agg["part"] == part]["row"]))


def line(ax, agg, part, row, label=None, scale=1.0, **kw):
    """Plot one (part, row) of an aggregate against its numeric columns (x times
    ``scale``, e.g. 100 for fractions shown in %); returns the series."""
    s = series(agg, part, row)
    if len(s):
        kw.setdefault("marker", "o")
        ax.plot(s.index * scale, s.to_numpy(), label=label or row, **kw)
    return s


def thesis(ax, x, y, label="thesis", **kw):
    """The thesis's printed values as black open diamonds, labelled for the legend."""
    style = dict(THESIS_STYLE)
    style.update(kw)
    return ax.plot(list(x), list(y), label=label, **style)


def finish(ax, xlabel, ylabel, title=None, legend=True, loc="best"):
    """Axis labels (with units), title, grid and (when there are labelled lines) a
    legend."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    ax.grid(True, alpha=0.3)
    if legend and ax.get_legend_handles_labels()[0]:
        ax.legend(loc=loc)


def figure_legend(fig, ax=None, ncol=None):
    """One legend for the whole figure, above the axes (for plots without free space;
    the handles of ``ax``, default the first axes)."""
    ax = ax or fig.axes[0]
    h, lab = ax.get_legend_handles_labels()
    if h:
        fig.legend(h, lab, loc="outside upper center", ncol=ncol or min(len(h), 4))


def _takes_rows(fn) -> bool:
    import inspect

    try:
        ps = inspect.signature(fn).parameters
    except (TypeError, ValueError):
        return False
    return "rows" in ps or any(q.kind == q.VAR_KEYWORD for q in ps.values())


def figures(experiment, agg, rows=None):
    """``[(stem, Figure)]`` of one registered experiment, and a list of error messages.

    ``rows`` (the experiment's ok results rows) are passed as ``rows=`` to an experiment
    whose ``figures`` accepts them; others get the aggregate alone."""
    from .tables import experiment_module

    fn = getattr(experiment_module(experiment), "figures", None)
    if fn is None or agg is None or agg.empty:
        return [], []
    try:
        return list((fn(agg, rows=rows) if _takes_rows(fn) else fn(agg)) or []), []
    except Exception as exc:  # noqa: BLE001
        plt.close("all")
        return [], [f"{experiment}: figure failed: {type(exc).__name__}: {exc}"]
