"""Simulated-rig captures read by Tables 6.1 / 6.2, made on demand instead of committed.

Each capture is what these two commands make (the simulated LED rig of
:mod:`psbench.capture.sim`, then every calibration step of :mod:`psbench.calibrate`)::

    psbench-capture rig=sim out=<results>/simrig/S surface=S lights=30x8+60x8 size=256 model=ts
    psbench-calibrate all <results>/simrig/S

for S in penny, mozart, spheres. The simulator is seeded, so the images, the
calibration and hence every IE of Table 6.1 are the same on every machine; only the
capture time stamps differ. A capture is made in a temporary folder beside its final
place and renamed into it when complete, so an interrupted or concurrent
``prepare`` never leaves a half-made folder. ``$PSBENCH_SIMRIG`` (used by the grids too)
puts the captures elsewhere; a folder that already exists is never touched.
"""
from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

SURFACES = ("penny", "mozart", "spheres")
SETTINGS = {"lights": "30x8+60x8", "size": 256, "model": "ts"}


def folder(root) -> Path:
    """Where the captures live: ``$PSBENCH_SIMRIG``, else ``<root>/simrig``."""
    env = os.environ.get("PSBENCH_SIMRIG")
    return Path(env).expanduser() if env else Path(root) / "simrig"


def prepare(root, scale=None) -> list[Path]:
    """Make the missing captures under :func:`folder` (``scale`` does not change them);
    returns the folders made."""
    made = []
    for s in SURFACES:
        out = folder(root) / s
        if not out.exists():
            print(f"making the simulated-rig capture {out} (once)", file=sys.stderr, flush=True)
            if make_capture(out, surface=s, **SETTINGS):
                made.append(out)
    return made


def make_capture(out, *, surface, lights, size, model) -> bool:
    """Capture ``surface`` with the simulated rig and calibrate it into ``out``.

    Returns False when another process made ``out`` first.
    """
    from psbench.calibrate import calibrate_folder, save_calibration
    from psbench.capture.controller import LedController
    from psbench.capture.sequence import capture_all
    from psbench.capture.sim import RigConfig, SimController, SimRig

    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    try:
        cap = tmp / out.name
        rig = SimRig(RigConfig(lights=lights, size=size, surface=surface, model=model))
        with SimController(rig.k) as dev:
            with LedController(dev.port, timeout=1.0) as ctl:
                capture_all(rig, ctl, cap, device=dev, progress=False)
        calib = calibrate_folder(cap)
        calib.meta["source"] = str(out)            # not the temporary folder
        save_calibration(calib, cap / "calibration")
        try:
            os.rename(cap, out)
        except OSError:
            if out.exists():                       # a concurrent prepare won the race
                return False
            raise
        return True
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
