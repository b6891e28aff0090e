"""Camera back-ends for rig capture.

Every camera has ``open()``, ``grab() -> (H, W) uint8/uint16``, ``close()``,
``bits`` and ``describe() -> dict``:

- :class:`OpenCVCamera` -- ``cv2.VideoCapture(index)`` (UVC/V4L2 webcams, some
  machine-vision cameras with a V4L2 driver); colour frames go to BT.601 luma;
  exposure set with ``CAP_PROP_EXPOSURE`` when given (units are driver-specific).
- :class:`FolderCamera` -- replays image files in sorted order (e.g. frames saved
  by a vendor tool), ``cv2.IMREAD_UNCHANGED`` so the bit depth is kept.
- :class:`psbench.capture.sim.SimCamera` -- the simulated rig's camera.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .controller import CaptureError

__all__ = ["OpenCVCamera", "FolderCamera"]


class OpenCVCamera:
    """A camera opened with OpenCV's ``VideoCapture``.

    Parameters
    ----------
    index : int
        Device index (``/dev/video<index>``).
    exposure : float, optional
        Value for ``CAP_PROP_EXPOSURE`` (auto exposure is switched off first).
    warmup : int
        Frames discarded after each LED change is up to the caller; ``warmup`` frames
        are discarded once after opening.
    flush : int
        Frames read and dropped before each returned frame (driver buffers may hold
        frames taken under the previous LED).
    """

    name = "opencv"

    def __init__(self, index=0, *, exposure=None, warmup=3, flush=2):
        self.index = int(index)
        self.exposure = exposure
        self.warmup = int(warmup)
        self.flush = int(flush)
        self._cap = None
        self.bits = 8

    def open(self):
        import cv2
        cap = cv2.VideoCapture(self.index)
        if not cap.isOpened():
            raise CaptureError(f"camera index {self.index} could not be opened with OpenCV "
                               "(not connected, busy, or no permission for /dev/video*)")
        if self.exposure is not None:
            cap.set(cv2.CAP_PROP_AUTO_EXPOSURE, 1)
            cap.set(cv2.CAP_PROP_EXPOSURE, float(self.exposure))
        self._cap = cap
        for _ in range(self.warmup):
            cap.read()
        return self

    def grab(self):
        import cv2
        if self._cap is None:
            self.open()
        for _ in range(self.flush):
            self._cap.grab()
        ok, frame = self._cap.read()
        if not ok or frame is None:
            raise CaptureError(f"camera index {self.index} returned no frame (disconnected?)")
        if frame.ndim == 3:
            frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
        self.bits = 8 if frame.dtype == np.uint8 else 16
        return frame

    def close(self):
        if self._cap is not None:
            self._cap.release()
            self._cap = None

    def describe(self):
        return {"camera": "opencv", "index": self.index, "exposure": self.exposure}


class FolderCamera:
    """Frames read from files in a folder, in sorted name order.

    Parameters
    ----------
    path : str or Path
    pattern : str
        Glob pattern (default ``*.png``).
    """

    name = "folder"

    def __init__(self, path, pattern="*.png"):
        self.path = Path(path)
        if not self.path.is_dir():
            raise CaptureError(f"camera folder {str(self.path)!r} does not exist")
        self.files = sorted(self.path.glob(pattern))
        if not self.files:
            raise CaptureError(f"camera folder {str(self.path)!r} has no {pattern} files")
        self.pos = 0
        self.bits = 8

    def open(self):
        return self

    def grab(self):
        import cv2
        if self.pos >= len(self.files):
            raise CaptureError(f"camera folder {str(self.path)!r} ran out of frames "
                               f"after {len(self.files)}")
        f = self.files[self.pos]
        self.pos += 1
        img = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise CaptureError(f"camera folder frame {str(f)!r} could not be read")
        if img.ndim == 3:
            img = cv2.cvtColor(img[..., :3], cv2.COLOR_BGR2GRAY)
        self.bits = 8 if img.dtype == np.uint8 else 16
        return img

    def close(self):
        pass

    def describe(self):
        return {"camera": "folder", "path": str(self.path)}
