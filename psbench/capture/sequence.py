"""Capture sequences: identify, dark frame, each LED in turn, all LEDs off at the end.

A capture is written into a temp folder beside the target and renamed into place
only when complete (:class:`psbench.io.atomic_dir`), so an interrupted capture
(error, device fault, Ctrl-C) leaves no complete-looking folder. All LEDs are
switched off in a ``finally`` block, also after errors and KeyboardInterrupt.

Folder layout (readable by :func:`psbench.io.read_dataset`): ``001.png`` ... (raw
camera frames, one per LED), ``dark.png`` (all LEDs off), ``filenames.txt``,
``light_directions.txt`` (nominal directions; a calibration replaces them),
``light_intensities.txt`` (ones; a calibration supplies the powers), optional
``mask.png`` / ``normals.npy``, and ``psbench.json`` (``lights``, ``ring``,
``bits``, ``exposure``, ``current_mA``, ``leds``, controller id/firmware, camera,
``raw: true``, UTC time). With calibration targets (:func:`capture_all`) the raw
target captures go to ``calibration_raw/<target>/``.
"""
from __future__ import annotations

import datetime as _dt
import json
import sys
from pathlib import Path

import numpy as np

from .._shared.deprecation import renamed_args
from ..io import atomic_dir, write_image
from ..io._common import json_default
from ..io._write import fmt_rows
from .controller import CaptureError

__all__ = ["capture", "capture_sequence", "capture_all", "Progress"]


class Progress:
    """A one-line progress display on a stream (stderr by default)."""

    def __init__(self, total, label="capture", stream=None, enabled=True):
        self.total = int(total)
        self.label = label
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled

    def update(self, done, what=""):
        if self.enabled:
            self.stream.write(f"\r{self.label}: {done}/{self.total} {what}".ljust(60))
            self.stream.flush()

    def close(self, text="done"):
        if self.enabled:
            self.stream.write(f"\r{self.label}: {text}".ljust(60) + "\n")
            self.stream.flush()


def capture_sequence(controller, camera, folder, *, leds, current_mA, dark=True,
                     progress=None, label="capture"):
    """Dark frame then one frame per LED into ``folder`` (which must exist).

    LEDs are switched one at a time (``LED i mA`` / grab / ``LED i 0``). Does not
    switch LEDs off at the end -- :func:`capture` does that in its ``finally``.

    Returns
    -------
    names : list of str
    """
    folder = Path(folder)
    n = len(leds) + (1 if dark else 0)
    prog = progress if progress is not None else Progress(n, label, enabled=False)
    done = 0
    if dark:
        controller.off()
        write_image(folder / "dark.png", camera.grab())
        done += 1
        prog.update(done, "dark")
    names = []
    for j, i in enumerate(leds):
        controller.led(i, current_mA)
        frame = camera.grab()
        controller.led(i, 0)
        name = f"{j + 1:03d}.png"
        write_image(folder / name, frame)
        names.append(name)
        done += 1
        prog.update(done, f"LED {i}")
    return names


def _write_layout(folder, names, lights, meta, object_mask=None, normals=None):
    folder = Path(folder)
    k = len(names)
    (folder / "filenames.txt").write_text("".join(n + "\n" for n in names))
    (folder / "light_directions.txt").write_text(fmt_rows(lights.directions))
    (folder / "light_intensities.txt").write_text(fmt_rows(np.ones((k, 3))))
    if object_mask is not None:
        write_image(folder / "mask.png", np.asarray(object_mask, bool).astype(np.uint8) * 255)
    if normals is not None:
        np.save(folder / "normals.npy", np.asarray(normals, np.float32))
    (folder / "psbench.json").write_text(json.dumps(meta, indent=1, default=json_default))


def _identify(controller, k):
    n_leds, fw = controller.identify()
    if k is not None and n_leds < k:
        raise CaptureError(f"LED controller on {controller.port_name!r} reports {n_leds} LEDs "
                           f"but the light layout has {k}")
    return n_leds, fw


def _base_meta(controller, camera, lights, leds, current_mA, fw, n_leds, extra):
    meta = {"format": "psbench-capture", "raw": True, "lights": lights.name,
            "ring": [int(r) for r in lights.ring], "leds": [int(i) for i in leds],
            "current_mA": int(current_mA), "bits": int(getattr(camera, "bits", 8)),
            "controller": {"port": controller.port_name, "n_leds": n_leds, "firmware": fw},
            "camera": camera.describe() if hasattr(camera, "describe") else {},
            "utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")}
    meta.update(extra or {})
    return meta


@renamed_args(renamed={"mask": "object_mask"})
def capture(controller, camera, out, lights, *, current_mA=350, leds=None, dark=True,
            object_mask=None, normals=None, meta=None, progress=True, overwrite=False):
    """Capture one PS image set into the folder ``out`` (atomically).

    Parameters
    ----------
    controller : LedController
    camera : camera back-end (``grab()``)
    out : str or Path
        Target folder; must not exist unless ``overwrite``.
    lights : Layout or str
        Nominal light layout, one entry per LED used.
    current_mA : int
    leds : sequence of int, optional
        Controller LED index of each light (default 0..k-1).
    object_mask, normals : (H, W) bool, (H, W, 3) float, optional
        Stored with the capture (simulator ground truth).
    meta : dict, optional
        Extra metadata for psbench.json.
    progress : bool
        Progress line on stderr.

    Returns
    -------
    Path of the finished folder.
    """
    from ..lights import layout
    lay = layout(lights)
    leds = list(range(lay.k)) if leds is None else [int(i) for i in leds]
    if len(leds) != lay.k:
        raise CaptureError(f"leds has {len(leds)} entries for {lay.k} lights")
    prog = Progress(lay.k + int(dark), "capture", enabled=progress)
    ok = False
    try:
        n_leds, fw = _identify(controller, max(leds) + 1)
        controller.off()
        with atomic_dir(out, overwrite=overwrite) as tmp:
            names = capture_sequence(controller, camera, tmp, leds=leds, current_mA=current_mA,
                                     dark=dark, progress=prog)
            md = _base_meta(controller, camera, lay, leds, current_mA, fw, n_leds, meta)
            _write_layout(tmp, names, lay, md, object_mask, normals)
        ok = True
    finally:
        err = controller.safe_off()
        prog.close("done" if ok else "aborted" + (f" (LEDs off failed: {err})" if err else ""))
    return Path(out)


def capture_all(rig, controller, out, *, device, current_mA=None, progress=True, overwrite=False,
                targets=("sphere", "white", "chart", "grid"), callback=None):
    """Simulated rig: capture the object plus calibration targets into one folder.

    ``out/`` is the object capture (with ground-truth ``normals.npy`` and
    ``mask.png``); ``out/calibration_raw/<target>/`` hold the target captures
    (``sphere`` and ``white``: one frame per LED; ``chart`` and ``grid``: one frame,
    with the chart patch boxes/radiances and grid pitch in their psbench.json).
    Everything is written atomically as one folder.

    Parameters
    ----------
    rig : SimRig
    controller : LedController
        The serial driver (talking to ``device`` over its pty).
    out : str or Path
    device : SimController
        The virtual controller whose LED state lights the virtual camera's scene.
    callback : callable(frame_index), optional
        Called by the camera before each frame.
    """
    from .sim import SimCamera
    cfg = rig.config
    mA = cfg.current_mA if current_mA is None else current_mA
    lay = rig.nominal
    leds = list(range(lay.k))
    n_frames = (lay.k + 1) * (1 + sum(t in ("sphere", "white") for t in targets)) \
        + sum(t in ("chart", "grid") for t in targets)
    prog = Progress(n_frames, "capture", enabled=progress)
    cam = SimCamera(rig, device, callback=callback)
    ok = False
    rig_meta = {"rig": "sim", "surface": cfg.surface, "size": cfg.size,
                "distance_px": rig.distance, "exposure": cfg.exposure}
    try:
        n_leds, fw = _identify(controller, lay.k)
        controller.off()
        with atomic_dir(out, overwrite=overwrite) as tmp:
            done = 0

            class _P:  # offsets a shared progress line
                def update(self, d, what=""):
                    prog.update(done + d, what)

            cam.target = "object"
            names = capture_sequence(controller, cam, tmp, leds=leds, current_mA=mA, progress=_P())
            done += len(names) + 1
            md = _base_meta(controller, cam, lay, leds, mA, fw, n_leds, dict(rig_meta, target="object"))
            sub = []
            for t in targets:
                d = tmp / "calibration_raw" / t
                d.mkdir(parents=True)
                cam.target = t
                if t in ("sphere", "white"):
                    tn = capture_sequence(controller, cam, d, leds=leds, current_mA=mA, progress=_P())
                    done += len(tn) + 1
                    tm = _base_meta(controller, cam, lay, leds, mA, fw, n_leds,
                                    dict(rig_meta, target=t))
                    msk = None
                    if t == "sphere":
                        from ..surfaces import make_surface
                        msk = make_surface("semisphere_disc", size=cfg.size).object_mask
                    _write_layout(d, tn, lay, tm, object_mask=msk)
                else:
                    controller.off()
                    write_image(d / "001.png", cam.grab())
                    done += 1
                    prog.update(done, t)
                    tm = {"format": "psbench-target", "target": t, "bits": cam.bits,
                          "camera": cam.describe()}
                    if t == "chart":
                        tm["boxes"] = [list(map(int, b)) for b in rig.chart_boxes]
                        tm["radiance"] = rig.chart_radiance.tolist()
                    else:
                        tm["pitch_mm"] = cfg.grid_mm
                    (d / "psbench.json").write_text(json.dumps(tm, indent=1, default=json_default))
                sub.append(t)
            md["calibration_raw"] = sub
            cam.target = "object"
            _write_layout(tmp, names, lay, md, rig.surface.object_mask, rig.surface.normals)
        ok = True
    finally:
        err = controller.safe_off()
        prog.close("done" if ok else "aborted" + (f" (LEDs off failed: {err})" if err else ""))
    return Path(out)
