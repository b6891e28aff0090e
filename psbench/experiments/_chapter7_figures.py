"""Figures of experiment ``chapter7``: the Figs. 7.3-7.9 analogues drawn from the panel
payload of :mod:`psbench.forensic.study`, and the CCFmax distributions."""
from __future__ import annotations

import numpy as np

from psbench.forensic._panels import decode

SISTER, OTHER = "#1a9850", "#7f7f7f"


def _show(ax, img, title=None, **kw):
    ax.imshow(img, interpolation="nearest", **kw)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.grid(False)
    for s in ax.spines.values():
        s.set_visible(False)
    if title:
        ax.set_title(title)


def score_figure(scores):
    """CCFmax of every pair per method (sister pairs green, non-sister grey), one panel per
    comparison region; the line in each column is the threshold gap (separation)."""
    from psbench.report.figures import new_figure

    regions = list(dict.fromkeys(scores["region"]))
    labels = list(dict.fromkeys(zip(scores["method"], scores["integrator"])))
    fig, axes = new_figure(ncols=1, nrows=len(regions), w=max(10.0, 0.62 * len(labels) + 2),
                           h=4.6)
    axes = np.atleast_1d(np.asarray(axes).ravel())
    rng = np.random.default_rng(0)
    for ax, region in zip(axes, regions):
        d = scores[scores["region"] == region]
        for i, (m, integ) in enumerate(labels):
            g = d[(d["method"] == m) & (d["integrator"] == integ)]
            for sister, colour, dx in ((False, OTHER, -0.12), (True, SISTER, 0.12)):
                v = g.loc[g["sister"] == sister, "ccf"].to_numpy()
                x = i + dx + rng.uniform(-0.07, 0.07, v.size)
                ax.plot(x, v, "o", ms=4, color=colour, alpha=0.75,
                        label=("sister pairs" if sister else "non-sister pairs") if i == 0
                        else None)
            s, n = g.loc[g["sister"], "ccf"], g.loc[~g["sister"], "ccf"]
            if len(s) and len(n):
                ok = s.min() > n.max()
                ax.plot([i - 0.3, i + 0.3], [s.min()] * 2, color=SISTER if ok else "#d73027",
                        lw=1.5)
                ax.plot([i - 0.3, i + 0.3], [n.max()] * 2, color="black", lw=1.0, ls=":")
        ax.set_xticks(range(len(labels)))
        ax.set_xticklabels([m if integ == "-" else f"{m}\n{integ}" for m, integ in labels],
                           rotation=60, ha="right", fontsize=10)
        ax.set_ylabel("CCFmax")
        ax.set_ylim(min(0.0, float(d["ccf"].min()) - 0.05), 1.02)
        ax.set_title(f"{region}: bar = lowest sister score (green: above, red: below the "
                     f"dotted highest non-sister score)", fontsize=12)
    handles, names = axes[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside upper center", ncol=2)
    return fig


def _montage_figure(rows, title):
    """Stacked montages (one per row of ``rows``: (label, base64 image))."""
    from psbench.report.figures import plt

    imgs = [(lab, decode(b)) for lab, b in rows]
    h = sum(im.shape[0] / im.shape[1] for _, im in imgs) * 14.0 + 0.6 * len(imgs)
    fig, axes = plt.subplots(len(imgs), 1, figsize=(14.0, h), layout="constrained")
    for ax, (lab, im) in zip(np.atleast_1d(axes), imgs):
        _show(ax, im, lab, cmap="gray" if im.ndim == 2 else None, vmin=0, vmax=255)
    fig.suptitle(title, fontsize=14)
    return fig


def _grid_figure(panels, kind, methods, cases, title, cmap=None):
    from psbench.report.figures import plt

    n = len(methods)
    fig, axes = plt.subplots(n, len(cases), figsize=(10.0, 4.9 * n), layout="constrained",
                             squeeze=False)
    for i, m in enumerate(methods):
        for j, c in enumerate(cases):
            key = f"{kind}/{m}/{c}"
            if key in panels["images"]:
                im = decode(panels["images"][key])
                _show(axes[i, j], im, f"({i + 1}) {m}: case {c}" + (" (aligned)" if j else ""),
                      cmap=cmap, vmin=0, vmax=255)
            else:
                axes[i, j].set_axis_off()
    fig.suptitle(title, fontsize=14)
    return fig


def panel_figures(p):
    """Figs. 7.3-7.9 analogues from the ``panels`` payload."""
    from psbench.report.figures import plt

    img = p["images"]
    gun, ca, cb = p["pair"]
    zen = [int(round(z)) for z in p.get("ring_zeniths", [])]
    figs = []
    ring_note = " / ".join(f"row {i + 1}: {z} deg ring" for i, z in enumerate(zen))
    figs.append(("fig7_3", _montage_figure(
        [("raw 8-bit images (counts 0-255)", img["raw"]),
         ("calibrated: float, max 1, shown scaled to the stack maximum; clipped (255) pixels "
          "red", img["calibrated"])],
        f"Figs. 7.3-7.4: the 16 images of gun {gun} case {ca} ({ring_note})")))
    figs.append(("fig7_5", _montage_figure(
        [("Th-Hi-Re-Sh: masked observations darker than the Lambert fit green (shadows), "
          "brighter blue (highlights)", img["masks"])],
        f"Fig. 7.5: Th-Hi-Re-Sh masks of gun {gun} case {ca} ({ring_note})")))
    wk = [k for k in img if k.startswith("weights_")]
    if wk:
        fig, axes = plt.subplots(1, len(wk), figsize=(6.0 * len(wk), 6.0), layout="constrained")
        for ax, k in zip(np.atleast_1d(axes), sorted(wk, key=lambda s: int(s.split("_")[1]))):
            im = _show(ax, decode(img[k]), f"{k.split('_')[1]} deg ring", cmap="gray",
                       vmin=0, vmax=255)
        sm = plt.cm.ScalarMappable(cmap="gray", norm=plt.Normalize(0, 1))
        fig.colorbar(sm, ax=list(np.atleast_1d(axes)), shrink=0.8, label="WPS ring weight")
        fig.suptitle(f"Fig. 7.6: WPS ring weights on the firing pin of gun {gun} case {ca} "
                     f"(white = high)", fontsize=14)
        figs.append(("fig7_6", fig))
    lab = "weighted Th-Hi-Re-Sh"
    if f"case/{lab}/{ca}" in img:
        fig, axes = plt.subplots(2, 2, figsize=(10.0, 10.4), layout="constrained")
        for j, c in enumerate((ca, cb)):
            _show(axes[0, j], decode(img[f"case/{lab}/{c}"]),
                  f"case {c}" + (f", aligned to case {ca}" if j else ""), cmap="gray",
                  vmin=0, vmax=255)
            _show(axes[1, j], decode(img[f"close/{lab}/{c}"]), f"case {c}: firing pin and breech face",
                  cmap="gray", vmin=0, vmax=255)
        fig.suptitle(f"Fig. 7.7: shaded heights of the sisters (gun {gun}), {lab}, Poisson "
                     f"integration; light from the upper left; close-ups contrast-stretched "
                     f"on the breech face", fontsize=13)
        figs.append(("fig7_7", fig))
    methods = ["ground truth"] + [m for m in ("None", "Th-Hi-Re-Sh", "weighted Th-Hi-Re-Sh", "WPS")]
    figs.append(("fig7_8", _grid_figure(
        p, "normals", methods, (ca, cb),
        f"Fig. 7.8: normals (RGB = (nx+1)/2, (ny+1)/2, nz) of the primers of cases {ca} and "
        f"{cb} (gun {gun}; case {cb} turned into case {ca}'s gun frame)")))
    figs.append(("fig7_9", _grid_figure(
        p, "shade", methods, (ca, cb),
        f"Fig. 7.9: shaded heights (Poisson) of the primers of cases {ca} and {cb}, contrast "
        f"stretched on the breech face",
        cmap="gray")))
    return figs
