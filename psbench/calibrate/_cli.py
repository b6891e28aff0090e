"""The ``psbench-calibrate`` command (entry point ``psbench.calibrate:main``)."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .._shared.checks import PsbenchError
from ..io import load_calibration, read_image, save_calibration
from ._steps import (calibrate_folder, load_or_new, step_dark, step_directions, step_pixelsize,
                     step_response, step_white)

__all__ = ["main"]


def main(argv=None):
    """``psbench-calibrate <step> ...``; see ``psbench-calibrate -h``."""
    from .._shared.warn import install

    install()                           # warnings as one psbench line each
    ap = argparse.ArgumentParser(
        prog="psbench-calibrate",
        description="Calibrate a photometric-stereo rig (thesis Chapter 6). Each step reads "
                    "target captures and updates a calibration folder (calibration.json + .npy), "
                    "which psbench.io.read_dataset applies automatically when it sits in a "
                    "capture folder as calibration/.")
    sub = ap.add_subparsers(dest="step", required=True)
    a = sub.add_parser("all", help="every step from <capture>/calibration_raw/{sphere,white,chart,grid}")
    a.add_argument("capture")
    a.add_argument("--out")
    a.add_argument("--distance", type=float, help="LED distance from the sphere centre (pixels)")
    a.add_argument("--flat-degree", type=int, default=4)
    a.add_argument("--response-degree", type=int, default=6)
    a.add_argument("--threshold", type=float)
    a.add_argument("--no-near-light", action="store_true")
    for name, hlp in (("dark", "hot pixels from a dark frame (PNG or folder with dark.png)"),
                      ("response", "inverse response from a gray-chart folder"),
                      ("directions", "light directions (and positions) from a specular-sphere folder"),
                      ("flat", "flat field from a white-target folder"),
                      ("powers", "light powers from a white-target folder"),
                      ("pixelsize", "pixel size from a grid-target folder")):
        p = sub.add_parser(name, help=hlp)
        p.add_argument("input")
        p.add_argument("--out", required=True, help="calibration folder to create/update")
        if name == "dark":
            p.add_argument("--threshold", type=float)
        if name == "response":
            p.add_argument("--degree", type=int, default=6)
        if name == "directions":
            p.add_argument("--distance", type=float,
                           help="LED distance from the sphere centre in pixels (enables near light)")
            p.add_argument("--fraction", type=float, default=0.8)
            p.add_argument("--center", type=float, nargs=2, metavar=("X", "Y"),
                           help="sphere centre in psbench's frame (pixels from the image centre, y up)")
            p.add_argument("--radius", type=float, help="sphere radius in pixels")
        if name == "flat":
            p.add_argument("--degree", type=int, default=4)
        if name == "pixelsize":
            p.add_argument("--pitch", type=float, help="grid pitch in mm")
    s = sub.add_parser("show", help="print a calibration")
    s.add_argument("calibration")
    args = ap.parse_args(argv)
    try:
        if args.step == "all":
            c = calibrate_folder(args.capture, args.out, distance=args.distance,
                                 flat_degree=args.flat_degree, response_degree=args.response_degree,
                                 threshold=args.threshold, near_light=not args.no_near_light)
            print(f"calibration steps: {', '.join(c.steps())} -> "
                  f"{args.out or Path(args.capture) / 'calibration'}")
            return 0
        if args.step == "show":
            c = load_calibration(args.calibration)
            print(json.dumps({"steps": c.steps(), "pixel_size_mm": c.pixel_size,
                              "powers": None if c.powers is None else np.round(c.powers, 4).tolist(),
                              "hot_pixels": None if c.hot is None else int(c.hot.sum()),
                              "meta": c.meta}, indent=1, default=str))
            return 0
        c = load_or_new(args.out)
        if args.step == "dark":
            src = Path(args.input)
            step_dark(c, read_image(src / "dark.png" if src.is_dir() else src), args.threshold)
        elif args.step == "response":
            step_response(c, args.input, args.degree)
        elif args.step == "directions":
            step_directions(c, args.input, distance=args.distance, fraction=args.fraction,
                            center=args.center, radius=args.radius)
        elif args.step == "flat":
            step_white(c, args.input, degree=args.degree, powers=False)
        elif args.step == "powers":
            step_white(c, args.input, flat=False)
        elif args.step == "pixelsize":
            step_pixelsize(c, args.input, args.pitch)
        save_calibration(c, args.out)
        print(f"{args.step}: done -> {args.out} (steps: {', '.join(c.steps())})")
        return 0
    except PsbenchError as e:
        print(f"psbench-calibrate: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
