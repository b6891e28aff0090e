"""Serial driver for a PSLED LED controller (protocol in :mod:`psbench.capture.protocol`).

Every failure raises a :class:`CaptureError` subclass with a message that names
the port and what happened:

- :class:`PortNotFound`  the port does not exist
- :class:`PortBusy`      another process holds the port (exclusive lock)
- :class:`DeviceTimeout` no complete reply line within ``timeout`` seconds
- :class:`ProtocolError` a reply that does not fit the protocol (garbage), or ``ERR``
- :class:`Disconnected`  the device went away (read/write error, hang-up)
"""
from __future__ import annotations

import errno
import os

from .._shared.checks import PsbenchError
from .protocol import ProtocolReplyError, parse_reply

try:  # termios errors (e.g. tcdrain on a hung-up tty) are not OSErrors
    import termios as _termios
    _IO_ERRORS = (OSError, _termios.error)
except ImportError:  # pragma: no cover - Windows
    _IO_ERRORS = (OSError,)

__all__ = ["CaptureError", "PortNotFound", "PortBusy", "DeviceTimeout", "ProtocolError",
           "Disconnected", "LedController"]


class CaptureError(PsbenchError):
    """A capture could not proceed (rig, port, device or camera problem)."""


class PortNotFound(CaptureError):
    pass


class PortBusy(CaptureError):
    pass


class DeviceTimeout(CaptureError):
    pass


class ProtocolError(CaptureError):
    pass


class Disconnected(CaptureError):
    pass


class LedController:
    """A PSLED controller on a serial port.

    Parameters
    ----------
    port : str
        Serial port name (``/dev/ttyUSB0``, ``COM3``, or a pty from the simulator).
    baudrate : int
    timeout : float
        Seconds to wait for each reply line (every read is bounded).
    max_line : int
        Longest accepted reply; longer input is treated as garbage.

    Use as a context manager; :meth:`close` does not switch LEDs off (the capture
    sequence does, in its ``finally``).
    """

    def __init__(self, port, *, baudrate=115200, timeout=1.0, max_line=256):
        import serial

        self.port_name = str(port)
        self.timeout = float(timeout)
        self.max_line = int(max_line)
        self.n_leds = None
        self.firmware = None
        if not os.path.exists(self.port_name) and not self.port_name.upper().startswith("COM"):
            raise PortNotFound(f"serial port {self.port_name!r} does not exist "
                               "(is the LED controller plugged in? check the port name)")
        try:
            self._ser = serial.Serial(self.port_name, baudrate=baudrate, timeout=self.timeout,
                                      write_timeout=self.timeout, exclusive=True)
        except serial.SerialException as e:
            err = getattr(e, "errno", None)
            text = str(e)
            if err in (errno.EBUSY, errno.EAGAIN, errno.EWOULDBLOCK) or "busy" in text.lower() \
                    or "lock" in text.lower():
                raise PortBusy(f"serial port {self.port_name!r} is busy: another program "
                               f"holds it ({text})") from None
            if err == errno.ENOENT or "No such file" in text:
                raise PortNotFound(f"serial port {self.port_name!r} does not exist ({text})") from None
            raise CaptureError(f"could not open serial port {self.port_name!r}: {text}") from None
        self._ser.reset_input_buffer()

    # -- low level
    def _readline(self, cmd):
        import serial

        try:
            line = self._ser.read_until(b"\n", self.max_line)
        except serial.SerialException as e:
            raise Disconnected(f"LED controller on {self.port_name!r} disconnected while "
                               f"waiting for the reply to {cmd!r} ({e})") from None
        except _IO_ERRORS as e:
            raise Disconnected(f"LED controller on {self.port_name!r} disconnected ({e})") from None
        if not line.endswith(b"\n"):
            if len(line) >= self.max_line:
                raise ProtocolError(f"LED controller on {self.port_name!r} sent garbage "
                                    f"({line[:40]!r}...) in reply to {cmd!r}")
            raise DeviceTimeout(
                f"LED controller on {self.port_name!r} did not answer {cmd!r} within "
                f"{self.timeout:g} s" + (f" (partial reply {line!r})" if line else "")
                + "; is it powered and running PSLED firmware?")
        try:
            return line.decode("ascii").rstrip("\r\n")
        except UnicodeDecodeError:
            raise ProtocolError(f"LED controller on {self.port_name!r} sent non-ASCII garbage "
                                f"{line[:40]!r} in reply to {cmd!r}") from None

    def command(self, cmd, expect="OK"):
        """Send one command line and return the parsed reply (see ``parse_reply``)."""
        import serial

        try:
            self._ser.write((cmd + "\n").encode("ascii"))
            self._ser.flush()
        except (serial.SerialException,) + _IO_ERRORS as e:
            raise Disconnected(f"LED controller on {self.port_name!r} disconnected: "
                               f"could not send {cmd!r} ({e})") from None
        line = self._readline(cmd)
        try:
            rep = parse_reply(line, expect)
        except ProtocolReplyError as e:
            raise ProtocolError(f"LED controller on {self.port_name!r}: {e} to {cmd!r}") from None
        if isinstance(rep, tuple) and rep and rep[0] == "ERR":
            raise ProtocolError(f"LED controller on {self.port_name!r} refused {cmd!r}: "
                                f"ERR {rep[1]} {rep[2]}")
        return rep

    # -- protocol
    def identify(self):
        """``ID?`` -> (n_leds, firmware)."""
        self.n_leds, self.firmware = self.command("ID?", "ID")
        return self.n_leds, self.firmware

    def led(self, index, current_mA):
        """Set LED ``index`` (0-based) to ``current_mA`` (0 = off)."""
        if self.n_leds is not None and not 0 <= int(index) < self.n_leds:
            raise CaptureError(f"LED index {index} out of range 0..{self.n_leds - 1}")
        self.command(f"LED {int(index)} {int(round(current_mA))}")

    def off(self):
        """All LEDs off."""
        self.command("OFF")

    def state(self):
        """Currents (mA) of every LED."""
        return self.command("STATE?", "STATE")

    def max_current(self):
        return self.command("MAX?", "MAX")

    def safe_off(self):
        """Best-effort ``OFF`` for cleanup paths: flushes stale input first, never raises.

        Returns
        -------
        str or None
            None on success, else the error text.
        """
        try:
            try:
                self._ser.reset_input_buffer()
            except Exception:
                pass
            self.off()
            return None
        except Exception as e:  # cleanup must not mask the original error
            return str(e)

    def close(self):
        try:
            self._ser.close()
        except Exception:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
