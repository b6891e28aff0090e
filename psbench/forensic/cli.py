"""The ``psbench-forensic`` command: compare two topographies, reconstruct one from images.

``psbench-forensic compare A.x3p B.x3p``
    Reads two X3P scans (:func:`psbench.io.read_x3p`; the finer is resampled to the
    coarser pixel size, and the command says so), compares them by congruent matching
    cells (:func:`psbench.forensic.cmc`: band-passed heights, cells on A registered on B)
    and prints CCFmax, the CMC count, the consensus pose and the times; writes a picture
    of the two band-passed scans with the cells drawn on both (default
    ``<results>/out/compare/<A>_vs_<B>_cmc.png``, ``<results>`` = ``$PSBENCH_RESULTS`` or
    ``results``: outputs stay out of the working tree).
``psbench-forensic reconstruct FOLDER --out heights.x3p``
    Reads a DiLiGenT-layout folder or a rig capture (:func:`psbench.io.read_dataset`,
    its calibration applied), reconstructs the heights in µm with the recommended recipe
    (:func:`psbench.forensic.reconstruct_heights`, its defaults) and writes them as X3P
    with a shaded PNG. The pixel size comes from ``--pixel-size``, else the capture's
    ``psbench.json`` (``pixel_size_um``) or its calibration.

Errors are one line (``psbench-forensic: error: ...``, exit status 2), progress goes to
stderr, results to stdout. :func:`main` takes the arguments as a list, so the command is
tested in-process.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError

__all__ = ["main"]

PROG = "psbench-forensic"


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line and status 2, as the other psbench commands
        raise PsbenchError(f"{message} (see {PROG} --help)")


def _parser():
    ap = _Parser(prog=PROG, description=(
        "Forensic use of photometric stereo: compare two breech-face topographies by "
        "congruent matching cells, or reconstruct a topography (X3P, um) from a "
        "photometric-stereo capture."))
    sub = ap.add_subparsers(dest="command", required=True, metavar="{compare,reconstruct}")
    c = sub.add_parser("compare", help="CCFmax, CMC count and pose of two X3P scans, and a "
                                       "picture of the matching cells",
                       description="Compare two X3P (ISO 25178-72) scans by congruent matching "
                                   "cells (CMC) and CCFmax.")
    c.add_argument("a", metavar="A.x3p", help="reference scan (the cells are laid on it)")
    c.add_argument("b", metavar="B.x3p", help="compared scan (each cell is registered on it)")
    c.add_argument("--picture", metavar="PNG",
                   help="where to write the picture of the cells (default: "
                        "results/out/compare/<A>_vs_<B>_cmc.png, under $PSBENCH_RESULTS "
                        "when set)")
    c.add_argument("--no-picture", action="store_true", help="write no picture")
    c.add_argument("--json", action="store_true",
                   help="print the result as one JSON object instead of text")
    r = sub.add_parser("reconstruct", help="heights (X3P, um) and a shaded PNG from a "
                                           "photometric-stereo capture",
                       description="Reconstruct a topography from a DiLiGenT-layout folder or "
                                   "a psbench rig capture and write it as X3P (um).")
    r.add_argument("folder", metavar="FOLDER",
                   help="DiLiGenT-layout folder or psbench capture (images, light_directions"
                        ".txt, light_intensities.txt, mask.png; psbench.json, calibration/)")
    r.add_argument("--out", required=True, metavar="X3P",
                   help="the X3P file to write (heights in um, NaN outside the object mask)")
    r.add_argument("--pixel-size", type=float, metavar="UM",
                   help="pixel size in um (default: the capture's psbench.json pixel_size_um "
                        "or its calibration's measured pixel size)")
    r.add_argument("--png", metavar="PNG",
                   help="where to write the shaded view of the heights (default: --out with "
                        "the suffix .png)")
    r.add_argument("--calibration", default="auto", metavar="auto|none|PATH",
                   help="calibration to apply: auto (the folder's own, default), none, or a "
                        "calibration folder")
    r.add_argument("--creator", help="creator written into the X3P metadata")
    return ap


def _progress(msg, t0=None):
    tail = "" if t0 is None else f" ({time.perf_counter() - t0:.2f} s)"
    print(f"{PROG}: {msg}{tail}", file=sys.stderr, flush=True)


# ----------------------------------------------------------------------------- compare
def _compare(args):
    from ..io import read_x3p
    from .scans import match_topographies

    for f in (args.a, args.b):
        if Path(f).suffix.lower() != ".x3p":
            raise PsbenchError(f"{f!r}: expected an .x3p file (ISO 25178-72 topography)")
    picture = None
    if not args.no_picture:
        root = Path(os.environ.get("PSBENCH_RESULTS") or "results").expanduser()
        picture = Path(args.picture) if args.picture else \
            root / "out" / "compare" / f"{Path(args.a).stem}_vs_{Path(args.b).stem}_cmc.png"
        if picture.suffix.lower() != ".png":
            raise PsbenchError(f"--picture {str(picture)!r}: expected a .png file")
    t0 = time.perf_counter()
    a, b = read_x3p(args.a), read_x3p(args.b)
    _progress(f"read {Path(args.a).name} ({a.shape[1]} x {a.shape[0]}, {a.pixel_size:g} um) "
              f"and {Path(args.b).name} ({b.shape[1]} x {b.shape[0]}, {b.pixel_size:g} um)", t0)
    try:
        from .cmc import cmc
    except ImportError:
        raise PsbenchError("congruent matching cells (psbench.forensic.cmc) are not part of "
                           "this installation of psbench") from None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        a, b = match_topographies(a, b)
    for w in caught:
        _progress(str(w.message))
    t1 = time.perf_counter()
    res = cmc(a.height, b.height, a.valid, b.valid, pixel_size=a.pixel_size)
    _progress("compared", t1)
    out = _summary(res, a, b, args)
    if picture is not None:
        from ._cmc_picture import cells_picture
        from ..io._pictures import write_png

        picture.parent.mkdir(parents=True, exist_ok=True)
        write_png(picture, cells_picture(res, a, b))
        out["picture"] = str(picture)
    if args.json:
        print(json.dumps(out))
    else:
        pose = out["pose"]
        verdict = "match" if out["match"] else "no match"
        print(f"{out['a']} vs {out['b']}: CCFmax {out['ccf']:.3f} | CMC {out['count']} of "
              f"{out['cells']} cells ({verdict}) | pose dx {pose['dx_um']:+.1f} um, "
              f"dy {pose['dy_um']:+.1f} um (down), theta {pose['theta_deg']:+.1f} deg | "
              f"pixel {out['pixel_size']:g} um")
        if picture is not None:
            print(f"picture: {picture}")
    return 0


def _summary(res, a, b, args):
    """The comparison as a JSON-able dict; the pose in µm (dx right, dy down) and degrees."""
    px = float(a.pixel_size)
    pose = {"dx_um": float(res.pose.dx) * px, "dy_um": float(res.pose.dy) * px,
            "theta_deg": float(res.pose.theta)}
    return {"a": Path(args.a).name, "b": Path(args.b).name, "ccf": float(res.ccf),
            "count": int(res.count), "cells": int(len(res.cells)),
            "match": bool(res.match), "pose": pose,
            "pixel_size": px}


# ----------------------------------------------------------------------------- reconstruct
def _pixel_size(args, ds):
    if args.pixel_size is not None:
        px = float(args.pixel_size)
        if not np.isfinite(px) or px <= 0:
            raise PsbenchError(f"--pixel-size must be a positive number of um, got "
                               f"{args.pixel_size!r}")
        return px, "--pixel-size"
    px = ds.meta.get("pixel_size_um")
    if px is None:
        raise PsbenchError(f"{args.folder}: no pixel size (neither psbench.json's pixel_size_um "
                           f"nor a calibration that measured it); pass --pixel-size UM")
    try:
        px = float(px)
    except (TypeError, ValueError):
        px = float("nan")
    if not np.isfinite(px) or px <= 0:
        raise PsbenchError(f"{args.folder}: pixel_size_um={ds.meta.get('pixel_size_um')!r} is "
                           f"not a positive number of um; pass --pixel-size UM")
    return px, "the calibration" if ds.meta.get("calibrated") else "psbench.json"


def _reconstruct(args):
    from ..io import read_dataset, write_x3p
    from ..io._pictures import text_px, titled, write_png
    from ..io._relief import height_picture
    from .recipe import reconstruct_heights

    out = Path(args.out)
    if out.suffix.lower() != ".x3p":
        raise PsbenchError(f"--out {args.out!r}: expected a .x3p file")
    png = Path(args.png) if args.png else out.with_suffix(".png")
    if png.suffix.lower() != ".png":
        raise PsbenchError(f"--png {args.png!r}: expected a .png file")
    folder = Path(args.folder)
    if not folder.is_dir():
        raise PsbenchError(f"FOLDER {args.folder!r} is not a folder; expected a DiLiGenT-layout "
                           f"folder or a psbench capture")
    t0 = time.perf_counter()
    ds = read_dataset(folder, calibration=args.calibration)
    k, H, W = ds.images.shape
    px, source = _pixel_size(args, ds)
    cal = f", calibrated ({', '.join(ds.meta.get('calibration_steps', []))})" \
        if ds.meta.get("calibrated") else ""
    _progress(f"read {k} images of {W} x {H}{cal}; pixel {px:g} um from {source}", t0)
    t1 = time.perf_counter()
    m = np.asarray(ds.object_mask, bool)
    z = reconstruct_heights(ds.images, ds.lights, object_mask=m, pixel_size=px)
    how = "psbench.forensic.reconstruct_heights"
    _progress(f"reconstructed by {how} (the recommended recipe)", t1)
    z = np.where(m, z, np.nan).astype(np.float32)
    meta = {"comment": f"reconstructed by psbench ({how}) from {folder.name}"}
    if args.creator:
        meta["creator"] = args.creator
    write_x3p(out, z, pixel_size=px, **meta)
    rel = height_picture(z / px, m, pixel_size=px)
    write_png(png, titled(rel, f"{folder.name}: heights (to scale, {px:g} um pixels)",
                          size=text_px(max(rel.shape[:2]), least=16)))
    v = z[m]
    print(f"{out}: {W} x {H} heights at {px:g} um, {int(m.sum())} valid, range "
          f"{float(v.min()):.2f} to {float(v.max()):.2f} um | shaded view: {png}")
    return 0


def main(args=None):
    """Console entry point ``psbench-forensic``.

    Parameters
    ----------
    args : list of str, optional
        Command-line arguments without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0, or 2 after a one-line error.
    """
    argv = list(sys.argv[1:] if args is None else args)
    try:
        ns = _parser().parse_args(argv)
        return _compare(ns) if ns.command == "compare" else _reconstruct(ns)
    except PsbenchError as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # a folder or file the environment refuses
        print(f"{PROG}: error: {exc.strerror or exc}: {exc.filename or ''}".rstrip(": "),
              file=sys.stderr)
        return 2
