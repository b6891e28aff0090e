"""Preview PNGs of surfaces and the ``psbench-surfaces`` command."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import registry
from .._shared.checks import PsbenchError
from .._shared.files import atomic_write
from ._make import make_surface
from ._surface import check_size

__all__ = ["write_preview", "main"]


def _shade(surface, light=(-1.0, 1.0, 1.5)):
    """Lambert shading max(0, n.l) with one light from the upper left (no cast shadows)."""
    ldir = np.asarray(light, dtype=np.float64)
    ldir = ldir / np.linalg.norm(ldir)
    return np.clip(surface.normals.astype(np.float64) @ ldir, 0.0, 1.0)


def write_preview(surface, path):
    """Write a PNG: height colour map and a shaded Lambert render side by side.

    Written atomically (temporary file in the same directory, then ``os.replace``).
    """
    import matplotlib
    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    m = surface.object_mask
    # heights in pixel units; in µm when the surface knows its pixel size (cartridge)
    um = getattr(surface, "pixel_size", None)
    h = np.ma.masked_array(surface.height * (um if um else 1.0), mask=~m)
    shade = np.where(m, _shade(surface), 0.0)
    fig = Figure(figsize=(7.2, 3.2), dpi=100)
    ax1, ax2 = fig.subplots(1, 2)
    im = ax1.imshow(h, cmap="viridis", interpolation="nearest")
    fig.colorbar(im, ax=ax1, fraction=0.046, pad=0.03, label="height [µm]" if um else "height [px]")
    ax1.set_title(f"{surface.name}: height", fontsize=9)
    ax2.imshow(shade, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
    ax2.set_title(f"Lambert, max zenith {float(surface.zenith[m].max()):.1f}°",
                  fontsize=9)
    for ax in (ax1, ax2):
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    atomic_write(path, lambda fh: fig.savefig(fh, format="png"), fsync=False)
    return path


def main(argv=None):
    """Console script ``psbench-surfaces``: write preview PNGs of the named surfaces."""
    import argparse

    # one preview per surface: an alias (another name of the same spec) adds none
    names = [n for n in registry.names("surfaces") if registry.get("surfaces", n).name == n]
    parser = argparse.ArgumentParser(
        prog="psbench-surfaces",
        description="Write preview PNGs (height colour map + Lambert shading) of psbench surfaces.")
    parser.add_argument("--out", default="surfaces", help="output directory (default: ./surfaces)")
    parser.add_argument("--size", type=int, default=256, help="grid size (default: 256)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace PNGs that already exist in --out (default: keep them)")
    parser.add_argument("--names", nargs="+", default=names, metavar="NAME",
                        help=f"surfaces to draw (default: all of {', '.join(names)})")
    args = parser.parse_args(argv)
    try:
        for name in args.names:
            registry.get("surfaces", name, what="--names")
        check_size(args.size)
    except PsbenchError as exc:
        parser.error(str(exc))
    for name in args.names:
        path = Path(args.out) / f"{name}.png"
        if path.exists() and not args.overwrite:     # e.g. the committed previews
            print(f"{path} exists, kept (--overwrite replaces it)")
            continue
        print(write_preview(make_surface(name, size=args.size), path))
    return 0
