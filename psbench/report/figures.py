"""Matplotlib (Agg) figures of the figure sweeps and tables, drawn from the aggregates.

Each ``fig_<experiment>(agg)`` returns a list of ``(stem, Figure)``; :func:`figures`
dispatches and never raises (a failing plot is reported as a message). Where the thesis
quotes numbers for a figure they are drawn as black crosses.
"""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from . import thesis_values as tv  # noqa: E402
from .tables import series  # noqa: E402

DPI = 80


def _fig(w=5.0, h=3.4, ncols=1):
    fig, axes = plt.subplots(1, ncols, figsize=(w * ncols, h), squeeze=False)
    return fig, axes[0]


def _rows(agg, part=""):
    if agg is None or agg.empty:
        return []
    return list(dict.fromkeys(agg[agg["part"] == part]["row"]))


def _line(ax, agg, part, row, label=None, **kw):
    s = series(agg, part, row)
    if len(s):
        ax.plot(s.index, s.to_numpy(), marker="o", ms=3, label=label or row, **kw)
    return s


def _finish(ax, xlabel, ylabel, title=None, legend=True):
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    if legend and ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)


def fig_fig4_3(agg):
    fig, (ax,) = _fig()
    for lab in ("Di", "Hi-Sh"):
        _line(ax, agg, "", lab)
        th = tv.VALUES["fig4_3"][""][lab]
        ax.plot([int(k) for k in th], list(th.values()), "kx", ms=6)
    _finish(ax, "image count n_i", "NE (deg)", "NE vs n_i, 45 deg ring (x = thesis)")
    return [("fig4_3", fig)]


def fig_fig4_4(agg):
    fig, (ax,) = _fig()
    for n in sorted(_rows(agg), key=float):
        _line(ax, agg, "", n, label=f"{n} images")
    _finish(ax, "source zenith (deg)", "NE (deg)", "Diffuse images, 5 % noise")
    return [("fig4_4", fig)]


def fig_fig4_7(agg):
    fig, axes = _fig(ncols=3, w=3.6)
    for ax, s in zip(axes, ("sombrero1", "sombrero2", "sombrero3")):
        for lab in ("Di", "Hi-Sh"):
            _line(ax, agg, s, lab)
        _finish(ax, "source zenith (deg)", "NE (deg)", s)
    fig.tight_layout()
    return [("fig4_7", fig)]


def fig_fig4_6(agg):
    fig, axes = _fig(ncols=3, w=3.6)
    for ax, s in zip(axes, ("sombrero1", "sombrero2", "sombrero3")):
        for comp in ("highlight", "shadow", "total"):
            _line(ax, agg, s, comp)
        _finish(ax, "source zenith (deg)", "IE", s)
    fig.tight_layout()
    return [("fig4_6", fig)]


def fig_fig4_9(agg):
    fig, (ax,) = _fig()
    for z in sorted(_rows(agg), key=float):
        _line(ax, agg, "", z, label=f"Z_source {z}")
    _finish(ax, "surface zenith (deg)", "mean NE (deg)", "sombrero2, 8 lights")
    return [("fig4_9", fig)]


def fig_fig4_10(agg):
    if agg is None or agg.empty:
        return []
    parts = sorted(agg["part"].unique(), key=float)
    fig, axes = _fig(ncols=max(1, len(parts)), w=3.6)
    for ax, z in zip(axes, parts):
        for comp in ("highlight", "shadow", "total"):
            _line(ax, agg, z, comp)
        ax.axvline(float(z) / 2, color="k", ls=":", lw=0.8)
        ax.axvline(90 - float(z), color="k", ls="--", lw=0.8)
        _finish(ax, "surface zenith (deg)", "IE", f"Z_source {z} (: Z/2, -- 90-Z)")
    fig.tight_layout()
    return [("fig4_10", fig)]


def fig_fig5_12(agg):
    fig, (ax,) = _fig()
    for f in _rows(agg):
        _line(ax, agg, "", f)
    _finish(ax, "noise (fraction of dynamic range)", "NE (deg)", "NE vs noise")
    return [("fig5_12", fig)]


def fig_fig5_13(agg):
    fig, (ax,) = _fig()
    for f in _rows(agg):
        _line(ax, agg, "", f)
    _finish(ax, "light count", "NE (deg)", "NE vs light count")
    return [("fig5_13", fig)]


def fig_fig5_14(agg):
    fig, (ax,) = _fig()
    for nz in sorted(_rows(agg), key=float):
        _line(ax, agg, "", nz, label=f"noise {float(nz) * 100:g} %")
    _finish(ax, "light count", "NE (deg)", "NL / xNL")
    return [("fig5_14", fig)]


def fig_table5_2(agg):
    out = []
    if agg is None or agg.empty:
        return out
    q = agg[agg["part"] == "qf"]
    if not q.empty:
        q = q.assign(name=q["row"].str.split("=").str[0],
                     val=q["row"].str.split("=").str[1].astype(float),
                     count=q["column"].str.split("/").str[0].astype(float),
                     noise=q["column"].str.split("/").str[1].astype(float))
        names = [n for n in ("k_low", "k_up", "t_NL", "t_Re", "k_Hi", "k_CS")
                 if n in set(q["name"])]
        fig, axes = plt.subplots(len(names), 2, figsize=(7.5, 2.1 * len(names)), squeeze=False)
        for i, name in enumerate(names):
            g = q[q["name"] == name]
            for nz, gg in g.groupby("noise"):
                m = gg.groupby("val")["value"].mean()
                axes[i][0].plot(m.index, m.to_numpy(), marker="o", ms=3, label=f"noise {nz:g}")
            for n, gg in g[g["noise"] > 0].groupby("count"):
                m = gg.groupby("val")["value"].mean()
                axes[i][1].plot(m.index, m.to_numpy(), marker="o", ms=3, label=f"{int(n)} img")
            for j in (0, 1):
                _finish(axes[i][j], name, "QF", legend=(i == 0))
        fig.tight_layout()
        out.append(("fig5_10", fig))
    r = agg[agg["part"] == "re_ne"]
    if not r.empty:
        fig, (ax,) = _fig()
        for z in sorted(r["column"].unique(), key=float):
            g = r[r["column"] == z]
            x = g["row"].astype(float).to_numpy()
            o = np.argsort(x)
            line, = ax.plot(x[o], g["value"].to_numpy()[o], marker="o", ms=3, label=f"Z {z}")
            ax.axvline(tv.t_re_formula(float(z), 8), color=line.get_color(), ls=":", lw=0.8)
        _finish(ax, "t_Re (deg)", "NE (deg)", "NE vs t_Re, 8 lights (: Eq. 5.1)")
        out.append(("fig5_11", fig))
    return out


def fig_table5_4(agg):
    if agg is None or agg.empty:
        return []
    fig, (ax,) = _fig(w=7.5, h=3.6)
    labels, ps, th = [], [], []
    for part, cfgs in tv.T54_PARTS.items():
        for cfg in cfgs:
            m = agg[(agg["part"] == part) & (agg["row"] == cfg)]
            labels.append(cfg)
            ps.append(float(m["value"].iloc[0]) if len(m) else np.nan)
            th.append(tv.value("table5_4", part, cfg, "ne"))
    x = np.arange(len(labels))
    ax.bar(x - 0.2, ps, 0.4, label="psbench")
    ax.bar(x + 0.2, th, 0.4, label="thesis")
    ax.set_xticks(x, labels, rotation=70, fontsize=6)
    _finish(ax, "", "NE (deg)", "Table 5.4")
    fig.tight_layout()
    return [("table5_4", fig)]


def fig_table5_5(agg):
    if agg is None or agg.empty:
        return []
    fig, axes = _fig(ncols=2, w=4.2)
    for r in tv.T55_ROWS:
        s = _line(axes[0], agg, "ne", r)
        color = axes[0].lines[-1].get_color() if len(s) else None
        axes[0].plot(tv.T55_COUNTS, [tv.value("table5_5", "ne", r, str(n)) for n in tv.T55_COUNTS],
                     ls="--", lw=0.8, alpha=0.6, color=color)
    _finish(axes[0], "image count n_i", "NE (deg)", "Hi-Sh (Table 5.5; dashed = thesis)")
    for r in ("1Z/None", "2Z/None"):
        _line(axes[1], agg, "di", r)
    _finish(axes[1], "image count n_i", "NE (deg)", "Di (Fig. 5.22)")
    fig.tight_layout()
    return [("table5_5", fig)]


def fig_table5_3(agg):
    if agg is None or agg.empty:
        return []
    fig, (ax,) = _fig(w=7.5, h=3.4)
    masks = [m for m in tv.T53_ALL_MASKS]
    vals = []
    for m in masks:
        s = agg[(agg["part"] == "all") & (agg["row"] == m) & (agg["column"] == "ne")]
        vals.append(float(s["value"].iloc[0]) if len(s) else np.nan)
    x = np.arange(len(masks))
    ax.bar(x - 0.2, vals, 0.4, label="psbench")
    ax.bar(x + 0.2, [tv.value("table5_3", "all", m, "ne") for m in masks], 0.4, label="thesis")
    ax.set_xticks(x, masks, rotation=70, fontsize=6)
    _finish(ax, "", "NE (deg)", "Table 5.3, all light sources")
    fig.tight_layout()
    return [("table5_3", fig)]


FIGURES = {k[4:]: v for k, v in globals().items() if k.startswith("fig_")}


def figures(experiment, agg):
    """``[(stem, Figure)]`` for one experiment, and a list of error messages."""
    fn = FIGURES.get(experiment)
    if fn is None or agg is None or agg.empty:
        return [], []
    try:
        return fn(agg), []
    except Exception as exc:  # noqa: BLE001
        plt.close("all")
        return [], [f"{experiment}: figure failed: {type(exc).__name__}: {exc}"]
