"""Image panels in the style of Figs. 5.15-5.17 and 5.24, drawn from ONE small scene set.

``psbench-report --panels`` calls :func:`build_panels`, which renders four test surfaces
(semisphere, sombrero, penny, mozart) at a small size with 8 lights at 45 deg and 10 %
noise (the thesis's panel configuration, but smaller), solves them with None, NL (its
8-image extension xNL), NL-Sh (xNL-Sh), Th, Th-Hi-Re-Sh and RA, and draws:

- ``masks.png``: the mask of the image lit from the left over that image, TP green,
  FP blue, FN red against the rendered highlight+shadow truth (Fig. 5.15);
- ``ne_maps.png``: per-pixel NE (Fig. 5.16), white = 20 deg or more;
- ``normals.png``: normals encoded as RGB [(nx+1)/2, (ny+1)/2, nz] (Fig. 5.17);
- ``wps.png``: NE maps of sombrero2 for PS 30x8, PS 60x8, PS 30x8+60x8 and WPS
  eZsourceZsurface (Fig. 5.24);
- ``height3d.png``: shaded 3D renders of the true sombrero2 heights and of the heights
  integrated from PS and WPS normals.

These panels are NOT read from the results store: they are illustrations produced by the
report command itself and labelled as such.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .html import save_figure, write_page

SURFACES = ("semisphere", "sombrero", "penny", "mozart")
MASKS = ("None", "xNL", "xNL-Sh", "Th", "Th-Hi-Re-Sh", "RA")
LABELS = {"xNL": "NL (xNL)", "xNL-Sh": "NL-Sh (xNL-Sh)"}


def encode_normals(normals, mask=None):
    """RGB image [(nx+1)/2, (ny+1)/2, nz] (thesis Fig. 5.17), clipped to 0..1."""
    n = np.asarray(normals, dtype=float)
    rgb = np.stack([(n[..., 0] + 1) / 2, (n[..., 1] + 1) / 2, n[..., 2]], axis=-1)
    rgb = np.clip(rgb, 0, 1)
    if mask is not None:
        rgb[~np.asarray(mask, bool)] = 0
    return rgb


def overlay(image, flagged, truth, mask=None):
    """Grey image with TP green, FP blue, FN red (thesis Fig. 5.15)."""
    img = np.asarray(image, dtype=float)
    lo, hi = np.nanpercentile(img, 1), np.nanpercentile(img, 99)
    g = np.clip((img - lo) / max(hi - lo, 1e-9), 0, 1)
    rgb = np.repeat(g[..., None], 3, axis=-1) * 0.8
    f, t = np.asarray(flagged, bool), np.asarray(truth, bool)
    if mask is not None:
        m = np.asarray(mask, bool)
        f, t = f & m, t & m
    rgb[f & t] = (0, 0.85, 0)
    rgb[f & ~t] = (0.1, 0.3, 1.0)
    rgb[~f & t] = (1.0, 0.1, 0.1)
    return rgb


def _left_index(lights):
    d = np.asarray(lights.directions)
    return int(np.argmin(d[:, 0]))


def build_panels(out, *, size=128, noise=0.1, seed=0, log=print):
    """Render + solve the panel scenes and write ``<out>/panels/*.png`` and panels.md/html.

    Returns the list of written PNG names.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import psbench as ps
    from psbench.integrate import integrate
    from psbench.metrics import normal_error_map

    out = Path(out)
    pdir = out / "panels"
    lay = ps.layout("45x8")
    li = _left_index(lay)
    cols = len(SURFACES)
    rows = len(MASKS)
    figm, axm = plt.subplots(rows + 1, cols, figsize=(1.9 * cols, 1.9 * (rows + 1)),
                             squeeze=False)
    fign, axn = plt.subplots(rows, cols, figsize=(1.9 * cols, 1.9 * rows), squeeze=False)
    figr, axr = plt.subplots(rows + 1, cols, figsize=(1.9 * cols, 1.9 * (rows + 1)),
                             squeeze=False)
    summary = []
    for j, name in enumerate(SURFACES):
        surf = ps.make_surface(name, size=size)
        sc = ps.render(surf, lay, model="ts", shadows=True, noise=noise, seed=seed)
        truth = sc.highlight | sc.shadow
        axm[0][j].imshow(sc.images[li], cmap="gray")
        axm[0][j].set_title(name, fontsize=8)
        axr[0][j].imshow(encode_normals(surf.normals, surf.mask))
        axr[0][j].set_title(f"{name} truth", fontsize=8)
        for i, mask in enumerate(MASKS):
            try:
                res = ps.solve(sc.images, lay, mask=mask, object_mask=surf.mask, seed=seed)
            except Exception as exc:  # noqa: BLE001
                log(f"panels: {name} {mask} failed: {exc}")
                continue
            ne = normal_error_map(res.normals, surf.normals)
            ne = np.where(surf.mask, ne, np.nan)
            summary.append(f"{name} {LABELS.get(mask, mask)}: mean NE {np.nanmean(ne):.2f} deg")
            flagged = ~np.asarray(res.valid, bool)[li]
            axm[i + 1][j].imshow(overlay(sc.images[li], flagged, truth[li], surf.mask))
            axn[i][j].imshow(np.clip(np.nan_to_num(ne, nan=0.0), 0, 20), cmap="gray",
                             vmin=0, vmax=20)
            axr[i + 1][j].imshow(encode_normals(res.normals, surf.mask))
            if j == 0:
                for ax in (axm[i + 1][0], axn[i][0], axr[i + 1][0]):
                    ax.set_ylabel(LABELS.get(mask, mask), fontsize=8)
    for axes in (axm, axn, axr):
        for row in axes:
            for ax in row:
                ax.set_xticks([])
                ax.set_yticks([])
    axm[0][0].set_ylabel("image (lit from left)", fontsize=8)
    axr[0][0].set_ylabel("truth", fontsize=8)
    figm.suptitle("Masks on the image lit from the left: TP green, FP blue, FN red", fontsize=9)
    fign.suptitle("Normal error maps (black 0, white >= 20 deg)", fontsize=9)
    figr.suptitle("Normals as RGB [(nx+1)/2, (ny+1)/2, nz]", fontsize=9)
    names = []
    for fig, stem in ((figm, "masks"), (fign, "ne_maps"), (figr, "normals")):
        fig.tight_layout()
        save_figure(fig, pdir / f"{stem}.png", dpi=72, palette=True)
        names.append(f"{stem}.png")

    # Fig. 5.24 / 5.25: sombrero2, 1Z vs 2Z PS vs WPS; heights in 3D
    surf = ps.make_surface("sombrero2", size=size)
    both = ps.layout("30x8+60x8")
    sc = ps.render(surf, both, model="ts", shadows=True, noise=0.05, seed=seed)
    rings = both.rings()
    cases = []
    for label, idx, kw in (("PS 30x8", rings[0], {}), ("PS 60x8", rings[1], {}),
                           ("PS 30x8+60x8", None, {}),
                           ("WPS eZsourceZsurface", None,
                            {"method": "wps", "weight": "eZsourceZsurface"})):
        try:
            if idx is None:
                res = ps.solve(sc.images, both, mask="None", object_mask=surf.mask, **kw)
            else:
                res = ps.solve(sc.images[idx], both.subset(idx), mask="None",
                               object_mask=surf.mask)
            cases.append((label, res))
        except Exception as exc:  # noqa: BLE001
            log(f"panels: sombrero2 {label} failed: {exc}")
    if cases:
        fig, axes = plt.subplots(1, len(cases), figsize=(2.4 * len(cases), 2.6), squeeze=False)
        for ax, (label, res) in zip(axes[0], cases):
            ne = np.where(surf.mask, normal_error_map(res.normals, surf.normals), np.nan)
            ax.imshow(np.clip(np.nan_to_num(ne), 0, 20), cmap="gray", vmin=0, vmax=20)
            ax.set_title(f"{label}\nNE {np.nanmean(ne):.2f} deg", fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
            summary.append(f"sombrero2 {label}: mean NE {np.nanmean(ne):.2f} deg")
        fig.suptitle("sombrero2, 5 % noise: NE maps (white >= 20 deg)", fontsize=9)
        fig.tight_layout()
        save_figure(fig, pdir / "wps.png", dpi=72, palette=True)
        names.append("wps.png")
        heights = [("truth", surf.height)]
        for label, res in cases[2:]:
            try:
                heights.append((label, integrate(res.normals, surf.mask)))
            except Exception as exc:  # noqa: BLE001
                log(f"panels: integrate {label} failed: {exc}")
        fig = plt.figure(figsize=(3.2 * len(heights), 3.0))
        from matplotlib.colors import LightSource

        ls = LightSource(azdeg=315, altdeg=45)
        step = max(1, size // 64)
        for k, (label, h) in enumerate(heights):
            ax = fig.add_subplot(1, len(heights), k + 1, projection="3d")
            z = np.where(surf.mask, np.asarray(h, float), np.nan)
            z = z - np.nanmean(z)
            z = np.nan_to_num(z)[::step, ::step]
            yy, xx = np.mgrid[0:z.shape[0], 0:z.shape[1]]
            rgb = ls.shade(z, cmap=plt.cm.gray, vert_exag=1.0, blend_mode="soft")
            ax.plot_surface(xx, -yy, z, facecolors=rgb, rstride=1, cstride=1, linewidth=0,
                            antialiased=False, shade=False)
            ax.set_title(label, fontsize=8)
            ax.set_axis_off()
            ax.view_init(elev=35, azim=-60)
        fig.suptitle("sombrero2 heights (pixel units), shaded 3D render", fontsize=9)
        save_figure(fig, pdir / "height3d.png", dpi=72)
        names.append("height3d.png")

    blocks = [("h1", "Image panels (illustration; rendered and solved by psbench-report --panels)"),
              ("p", f"One scene per surface at {size} x {size} (the thesis used 512 x 512), 8 "
                    f"lights at 45 deg, TS + shadows, {noise * 100:g} % noise, seed {seed}. "
                    "These panels are not read from the results store."),
              ("list", summary)]
    for n, cap in (("masks.png", "Fig. 5.15 style: masks (TP green, FP blue, FN red)"),
                   ("ne_maps.png", "Fig. 5.16 style: NE maps"),
                   ("normals.png", "Fig. 5.17 style: RGB-encoded normals"),
                   ("wps.png", "Fig. 5.24 style: sombrero2 PS 30/60/30+60 vs WPS"),
                   ("height3d.png", "Shaded 3D render of integrated heights")):
        if n in names:
            blocks.append(("img", f"panels/{n}", cap))
    write_page(out, "panels", blocks, "psbench image panels")
    log(f"panels written to {pdir}")
    return names
