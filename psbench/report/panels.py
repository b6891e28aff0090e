"""Image panels in the style of Figs. 5.15-5.17 and 5.24, drawn from ONE small scene set.

``psbench-report --panels`` calls :func:`build_panels`, which renders four test surfaces
(semisphere, sombrero, penny, mozart) at a small size with 8 lights at 45 deg and 10 %
noise (the thesis's panel configuration, but smaller), solves them with None, NL (its
8-image extension xNL), NL-Sh (xNL-Sh), Th, Th-Hi-Re-Sh and RA, and draws:

- ``masks.png``: the mask of the image lit from the left over that image, TP green,
  FP blue, FN red against the rendered highlight+shadow truth (Fig. 5.15);
- ``ne_maps.png``: per-pixel NE (Fig. 5.16) in a perceptual colour map over a fixed
  0-20 deg range with a colour bar;
- ``normals.png``: normals encoded as RGB [(nx+1)/2, (ny+1)/2, nz] (Fig. 5.17);
- ``wps.png``: NE maps (same colours) of sombrero2 for PS 30x8, PS 60x8, PS 30x8+60x8
  and WPS eZsourceZsurface (Fig. 5.24);
- ``height3d.png``: shaded 3D renders (colour = height) of the true sombrero2 heights
  and of the heights integrated from PS and WPS normals;
- the page lists the mean NE of every panel in tables.

These panels are NOT read from the results store: they are illustrations produced by the
report command itself and labelled as such.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .._shared.deprecation import renamed_args
from ..io.html import save_figure, write_page

SURFACES = ("semisphere", "sombrero", "penny", "mozart")
MASKS = ("None", "xNL", "xNL-Sh", "Th", "Th-Hi-Re-Sh", "RA")
LABELS = {"xNL": "NL (xNL)", "xNL-Sh": "NL-Sh (xNL-Sh)"}


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def encode_normals(normals, *, object_mask=None):
    """RGB image [(nx+1)/2, (ny+1)/2, nz] (thesis Fig. 5.17), clipped to 0..1.

    Parameters
    ----------
    normals : (H, W, 3) array_like
        Normals, x right, y up, z towards the camera.
    object_mask : (H, W) bool, optional
        Object region; pixels outside it are black. Formerly ``mask=`` (or the second
        positional argument), which still works with a DeprecationWarning.

    Returns
    -------
    rgb : (H, W, 3) float64
        In 0..1.
    """
    n = np.asarray(normals, dtype=float)
    rgb = np.stack([(n[..., 0] + 1) / 2, (n[..., 1] + 1) / 2, n[..., 2]], axis=-1)
    rgb = np.clip(rgb, 0, 1)
    if object_mask is not None:
        rgb[~np.asarray(object_mask, bool)] = 0
    return rgb


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def overlay(image, flagged, truth, *, object_mask=None):
    """Grey image with TP green, FP blue, FN red (thesis Fig. 5.15).

    Parameters
    ----------
    image : (H, W) array_like
        The image, shown in grey (1st-99th percentile stretch).
    flagged : (H, W) bool
        Pixels the mask excluded.
    truth : (H, W) bool
        Pixels truly in highlight or shadow.
    object_mask : (H, W) bool, optional
        Object region; outside it nothing is coloured. Formerly ``mask=`` (or the
        fourth positional argument), which still works with a DeprecationWarning.

    Returns
    -------
    rgb : (H, W, 3) float64
        In 0..1.
    """
    img = np.asarray(image, dtype=float)
    lo, hi = np.nanpercentile(img, 1), np.nanpercentile(img, 99)
    g = np.clip((img - lo) / max(hi - lo, 1e-9), 0, 1)
    rgb = np.repeat(g[..., None], 3, axis=-1) * 0.8
    f, t = np.asarray(flagged, bool), np.asarray(truth, bool)
    if object_mask is not None:
        m = np.asarray(object_mask, bool)
        f, t = f & m, t & m
    rgb[f & t] = (0, 0.85, 0)
    rgb[f & ~t] = (0.1, 0.3, 1.0)
    rgb[~f & t] = (1.0, 0.1, 0.1)
    return rgb


def _left_index(lights):
    d = np.asarray(lights.directions)
    return int(np.argmin(d[:, 0]))


NE_MAX = 20.0        # degrees: fixed colour range of every NE map
NE_CMAP = "magma"    # perceptual, dark = small error


def _ne_image(ax, ne, object_mask):
    """An NE map on ``ax`` with the fixed colour range; outside the object white.

    ``ne`` and ``object_mask`` are (H, W): degrees and the object region.
    """
    import numpy.ma as ma

    img = ax.imshow(ma.masked_where(~np.asarray(object_mask, bool), ne), cmap=_cmap(), vmin=0.0,
                    vmax=NE_MAX, interpolation="nearest")
    return img


def _cmap():
    import matplotlib

    return matplotlib.colormaps[NE_CMAP].with_extremes(bad="white")


def _ne_colorbar(fig, img, axes):
    cb = fig.colorbar(img, ax=axes, shrink=0.8, extend="max", pad=0.02)
    cb.set_label(f"NE (deg), fixed range 0-{NE_MAX:g}")
    return cb


def _off(axes):
    for ax in np.ravel(axes):
        ax.set_xticks([])
        ax.set_yticks([])


def _height_render(fig, heights, object_mask, size, log):
    """Shaded 3D surfaces of ``heights`` [(label, (H, W))] side by side, over the
    (H, W) bool ``object_mask``."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import LightSource

    ls = LightSource(azdeg=315, altdeg=55)
    step = max(1, size // 96)
    m = np.asarray(object_mask, bool)[::step, ::step]
    for k, (label, h) in enumerate(heights):
        ax = fig.add_subplot(1, len(heights), k + 1, projection="3d")
        z = np.where(object_mask, np.asarray(h, float), np.nan)
        z = z - np.nanmin(z)
        z = z[::step, ::step]
        zf = np.where(m, z, 0.0)
        yy, xx = np.mgrid[0:z.shape[0], 0:z.shape[1]]
        rgb = ls.shade(zf, cmap=plt.cm.viridis, vert_exag=2.0, blend_mode="soft",
                       vmin=0.0, vmax=float(np.nanmax(z)) or 1.0)
        rgb[~m] = (0.92, 0.92, 0.92, 1.0)
        ax.plot_surface(xx * step, -yy * step, zf, facecolors=rgb, rstride=1, cstride=1,
                        linewidth=0, antialiased=False, shade=False)
        ax.set_box_aspect((1, 1, 0.45), zoom=1.15)
        ax.set_title(label, fontsize=14, y=0.98)
        ax.set_axis_off()
        ax.view_init(elev=38, azim=-58)


def build_panels(out, *, size=128, noise=0.1, seed=0, log=print):
    """Render + solve the panel scenes and write ``<out>/panels/*.png`` and panels.md/html.

    Returns the list of written PNG names.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import pandas as pd
    from matplotlib.patches import Patch

    import psbench as ps
    from psbench.integrate.poisson import integrate
    from psbench.metrics.errors import normal_error_map

    out = Path(out)
    pdir = out / "panels"
    lay = ps.layout("45x8")
    li = _left_index(lay)
    cols, rows = len(SURFACES), len(MASKS)
    cell = 2.7
    figm, axm = plt.subplots(rows + 1, cols, figsize=(cell * cols, cell * (rows + 1)),
                             squeeze=False, layout="constrained")
    fign, axn = plt.subplots(rows, cols, figsize=(cell * cols + 1.6, cell * rows),
                             squeeze=False, layout="constrained")
    figr, axr = plt.subplots(rows + 1, cols, figsize=(cell * cols, cell * (rows + 1)),
                             squeeze=False, layout="constrained")
    table = {}
    img = None
    for j, name in enumerate(SURFACES):
        surf = ps.make_surface(name, size=size)
        sc = ps.render(surf, lay, model="ts", shadows=True, noise=noise, seed=seed)
        truth = sc.highlight | sc.shadow
        axm[0][j].imshow(sc.images[li], cmap="gray")
        axm[0][j].set_title(name, fontsize=14)
        axn[0][j].set_title(name, fontsize=14)
        axr[0][j].imshow(encode_normals(surf.normals, object_mask=surf.object_mask))
        axr[0][j].set_title(name, fontsize=14)
        for i, mask in enumerate(MASKS):
            try:
                res = ps.solve(sc.images, lay, mask=mask, object_mask=surf.object_mask, seed=seed)
            except Exception as exc:  # noqa: BLE001
                log(f"panels: {name} {mask} failed: {exc}")
                continue
            ne = normal_error_map(res.normals, surf.normals)
            ne = np.where(surf.object_mask, ne, np.nan)
            table.setdefault(LABELS.get(mask, mask), {})[name] = float(np.nanmean(ne))
            flagged = ~np.asarray(res.valid, bool)[li]
            axm[i + 1][j].imshow(overlay(sc.images[li], flagged, truth[li],
                                              object_mask=surf.object_mask))
            img = _ne_image(axn[i][j], ne, surf.object_mask)
            axr[i + 1][j].imshow(encode_normals(res.normals, object_mask=surf.object_mask))
            if j == 0:
                for ax in (axm[i + 1][0], axn[i][0], axr[i + 1][0]):
                    ax.set_ylabel(LABELS.get(mask, mask), fontsize=13)
    for axes in (axm, axn, axr):
        _off(axes)
    axm[0][0].set_ylabel("image lit from the left", fontsize=13)
    axr[0][0].set_ylabel("ground truth", fontsize=13)
    figm.suptitle("Masks on the image lit from the left", fontsize=15)
    figm.legend(handles=[Patch(color=(0, 0.85, 0), label="TP: flagged, truly highlight/shadow"),
                         Patch(color=(0.1, 0.3, 1.0), label="FP: flagged, truly clean"),
                         Patch(color=(1.0, 0.1, 0.1), label="FN: missed highlight/shadow")],
                loc="outside lower center", ncol=3, fontsize=12)
    fign.suptitle("Per-pixel normal error (NE) of each mask", fontsize=15)
    if img is not None:
        _ne_colorbar(fign, img, axn)
    figr.suptitle("Normals as RGB [(nx+1)/2, (ny+1)/2, nz] (thesis Fig. 5.17)", fontsize=15)
    names = []
    for fig, stem in ((figm, "masks"), (fign, "ne_maps"), (figr, "normals")):
        save_figure(fig, pdir / f"{stem}.png", dpi=100, palette=True)
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
                res = ps.solve(sc.images, both, mask="None", object_mask=surf.object_mask, **kw)
            else:
                res = ps.solve(sc.images[idx], both.subset(idx), mask="None",
                               object_mask=surf.object_mask)
            cases.append((label, res))
        except Exception as exc:  # noqa: BLE001
            log(f"panels: sombrero2 {label} failed: {exc}")
    wps_rows = []
    if cases:
        fig, axes = plt.subplots(1, len(cases), figsize=(3.0 * len(cases) + 1.6, 3.6),
                                 squeeze=False, layout="constrained")
        for ax, (label, res) in zip(axes[0], cases):
            ne = np.where(surf.object_mask, normal_error_map(res.normals, surf.normals), np.nan)
            img = _ne_image(ax, ne, surf.object_mask)
            ax.set_title(f"{label}\nmean NE {np.nanmean(ne):.2f} deg", fontsize=13)
            wps_rows.append({"method": label, "mean NE (deg)": f"{np.nanmean(ne):.2f}",
                             "median NE (deg)": f"{np.nanmedian(ne):.2f}"})
        _off(axes)
        _ne_colorbar(fig, img, axes)
        fig.suptitle("sombrero2, 5 % noise: NE maps, 1Z vs 2Z PS vs WPS", fontsize=15)
        save_figure(fig, pdir / "wps.png", dpi=100, palette=True)
        names.append("wps.png")
        heights = [("true heights", surf.height)]
        for label, res in cases[2:]:
            try:
                heights.append((f"integrated from {label}", integrate(res.normals, object_mask=surf.object_mask)))
            except Exception as exc:  # noqa: BLE001
                log(f"panels: integrate {label} failed: {exc}")
        fig = plt.figure(figsize=(5.0 * len(heights), 4.6))
        _height_render(fig, heights, surf.object_mask, size, log)
        fig.suptitle("sombrero2 heights, shaded 3D render (colour = height)", fontsize=15,
                     y=1.04)
        fig.subplots_adjust(left=0, right=1, bottom=0, top=0.92, wspace=0)
        save_figure(fig, pdir / "height3d.png", dpi=100)
        names.append("height3d.png")

    ne_tab = pd.DataFrame([{"mask": m, **{s: f"{v[s]:.2f}" if s in v else "—"
                                          for s in SURFACES}} for m, v in table.items()],
                          columns=["mask", *SURFACES])
    blocks = [("h1", "Image panels (illustration; rendered and solved by psbench-report --panels)"),
              ("p", f"One scene per surface at {size} x {size} (the thesis used 512 x 512), 8 "
                    f"lights at 45 deg, TS + shadows, {noise * 100:g} % noise, seed {seed}. "
                    "These panels are not read from the results store. Back to "
                    "[the index](index.html)."),
              ("h2", "Mean NE of each mask"),
              ("table", ne_tab, "rows: mask; columns: surface; values: mean NE over the "
                                "object in deg")]
    if wps_rows:
        blocks += [("h2", "sombrero2: 1Z vs 2Z PS vs WPS (5 % noise)"),
                   ("table", pd.DataFrame(wps_rows))]
    blocks.append(("h2", "Panels"))
    for n, cap in (("masks.png", "Fig. 5.15 style: masks (TP green, FP blue, FN red)"),
                   ("ne_maps.png", f"Fig. 5.16 style: NE maps ({NE_CMAP} colour map, fixed "
                                   f"range 0-{NE_MAX:g} deg)"),
                   ("normals.png", "Fig. 5.17 style: RGB-encoded normals"),
                   ("wps.png", "Fig. 5.24 style: sombrero2 PS 30/60/30+60 vs WPS"),
                   ("height3d.png", "Shaded 3D render of true and integrated heights")):
        if n in names:
            blocks.append(("img", f"panels/{n}", cap))
    write_page(out, "panels", blocks, "psbench image panels")
    log(f"panels written to {pdir}")
    return names
