"""PSLED line protocol between psbench and an LED controller.

Transport: a serial port (USB CDC/FTDI or a pseudo-terminal for the simulator),
8N1, default 115200 baud. Messages are ASCII lines terminated by ``\\n``
(a preceding ``\\r`` is ignored). The host sends one command and waits for one
reply line before sending the next; every read has a timeout (default 1 s).
LED indices are 0-based; currents are integer milliamperes.

=====================  ==============================  =========================================
host sends             device replies                  meaning
=====================  ==============================  =========================================
``ID?``                ``PSLED <n_leds> <fw>``         identify: LED count and firmware version
``LED <i> <mA>``       ``OK``                          set LED i to mA (0 = off); others unchanged
``OFF``                ``OK``                          all LEDs off
``STATE?``             ``STATE <mA_0> ... <mA_n-1>``   current of every LED
``MAX?``               ``MAX <mA>``                    largest allowed current
=====================  ==============================  =========================================

Errors: ``ERR <code> <text>`` with codes

- ``1`` unknown command
- ``2`` malformed arguments
- ``3`` LED index out of range
- ``4`` current out of range (negative or above ``MAX?``)
- ``5`` internal fault (over-temperature, driver fault)

A controller must switch all LEDs off when it powers up and when its host
connection is lost (USB suspend / DTR drop); psbench still sends ``OFF`` at the
end of every capture, also after errors and Ctrl-C.
"""
from __future__ import annotations

import re

__all__ = ["ERR_UNKNOWN", "ERR_ARGS", "ERR_INDEX", "ERR_CURRENT", "ERR_FAULT",
           "parse_command", "parse_reply", "ProtocolReplyError", "ERROR_TEXT"]

ERR_UNKNOWN, ERR_ARGS, ERR_INDEX, ERR_CURRENT, ERR_FAULT = 1, 2, 3, 4, 5
ERROR_TEXT = {1: "unknown command", 2: "malformed arguments", 3: "LED index out of range",
              4: "current out of range", 5: "internal fault"}

_ID = re.compile(r"^PSLED (\d+) (\S+)$")
_ERR = re.compile(r"^ERR (\d+)(?: (.*))?$")
_STATE = re.compile(r"^STATE((?: \d+)*)$")
_MAX = re.compile(r"^MAX (\d+)$")


class ProtocolReplyError(ValueError):
    """A reply line that does not fit the protocol."""


def parse_command(line):
    """Split a command line into (name, args); raises ValueError on bad syntax.

    Returns
    -------
    (str, tuple of int)
    """
    parts = line.strip().split()
    if not parts:
        raise ValueError("empty command")
    name, args = parts[0].upper(), parts[1:]
    if name in ("ID?", "OFF", "STATE?", "MAX?"):
        if args:
            raise ValueError(f"{name} takes no arguments")
        return name, ()
    if name == "LED":
        if len(args) != 2 or not all(re.fullmatch(r"-?\d+", a) for a in args):
            raise ValueError("LED needs two integers: LED <i> <mA>")
        return name, (int(args[0]), int(args[1]))
    raise KeyError(name)


def parse_reply(line, expect):
    """Check one reply line against the command sent.

    Parameters
    ----------
    line : str
        Reply without the newline.
    expect : {"ID", "OK", "STATE", "MAX"}

    Returns
    -------
    ("ERR", code, text) for error replies, else the parsed value:
    ``(n_leds, fw)`` for ID, ``None`` for OK, list of mA for STATE, int for MAX.

    Raises
    ------
    ProtocolReplyError
        For anything else (garbage).
    """
    m = _ERR.match(line)
    if m:
        return ("ERR", int(m.group(1)), m.group(2) or "")
    if expect == "OK" and line == "OK":
        return None
    if expect == "ID":
        m = _ID.match(line)
        if m:
            return int(m.group(1)), m.group(2)
    if expect == "STATE":
        m = _STATE.match(line)
        if m:
            return [int(v) for v in m.group(1).split()]
    if expect == "MAX":
        m = _MAX.match(line)
        if m:
            return int(m.group(1))
    raise ProtocolReplyError(f"unexpected reply {line!r} (expected {expect} reply)")
