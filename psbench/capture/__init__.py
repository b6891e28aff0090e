"""Rig capture: PSLED serial LED controller, camera back-ends, capture sequences, simulated rig.

- :mod:`~psbench.capture.protocol`   the PSLED line protocol (documented there)
- :mod:`~psbench.capture.controller` :class:`LedController` (pyserial driver) and errors
- :mod:`~psbench.capture.camera`     OpenCV ``VideoCapture`` and folder cameras
- :mod:`~psbench.capture.sim`        pty-served virtual controller and virtual camera
- :mod:`~psbench.capture.sequence`   atomic capture folders, LEDs off in ``finally``
- :mod:`~psbench.capture.cli`        the ``psbench-capture`` command
"""
from .controller import (CaptureError, DeviceTimeout, Disconnected, LedController, PortBusy,
                         PortNotFound, ProtocolError)
from .sequence import capture, capture_all

__all__ = ["CaptureError", "DeviceTimeout", "Disconnected", "LedController", "PortBusy",
           "PortNotFound", "ProtocolError", "capture", "capture_all"]
