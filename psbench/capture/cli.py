"""``psbench-capture``: capture a PS image set with a rig (default: the simulated one).

Arguments are ``key=value`` pairs (Hydra style, no dashes)::

    psbench-capture rig=sim                    # -> results/captures/sim_<UTC time>/
    psbench-capture rig=sim out=DIR surface=penny lights=30x4+60x4 size=128
    psbench-capture rig=serial port=/dev/ttyUSB0 camera=0 out=DIR lights=30x8+60x8 current=350

Keys
----
rig        ``sim`` (default) or ``serial``
out        output folder; must not exist unless ``overwrite=true`` (default: a new
           folder ``<results>/captures/<rig>_<UTC time>/``, where ``<results>`` is
           ``$PSBENCH_RESULTS`` or ``results`` in the current directory, as for
           ``psbench``). The folder written is printed on stdout.
lights     nominal LED layout in ring notation (default ``30x4+60x4``); LED i of the
           controller is light i of the layout (``leds=3,4,5`` to remap)
current    LED current in mA (default 350)
progress   ``true``/``false`` progress line on stderr (default true)
overwrite  replace ``out`` if it exists (default false)

serial rig: ``port`` (serial device), ``baud`` (115200), ``timeout`` (s, default 1),
``camera`` (OpenCV device index, or a folder of frames to replay), ``exposure``
(CAP_PROP_EXPOSURE value), ``target`` (free text stored in psbench.json, e.g. sphere).

sim rig: ``surface`` (psbench surface name, default penny), ``size`` (128), ``seed``,
``targets`` (``all`` = sphere,white,chart,grid (default), ``none``, or a comma list),
``distance`` (LED distance in pixels), ``gamma``, ``vignette``, ``hot_pixels``,
``model``, ``fault`` (silence|garbage|disconnect|error) and ``fault_after`` (commands).

Exit status: 0 on success, 2 on bad arguments or capture errors, 130 on Ctrl-C.
"""
from __future__ import annotations

import sys
from pathlib import Path

from .._shared.checks import PsbenchError

_SIM_KEYS = {"surface": str, "size": int, "seed": int, "distance": float, "gamma": float,
             "vignette": float, "hot_pixels": int, "model": str, "exposure": float,
             "power_spread": float, "read_noise": float}
# lower bounds (value, strict) of the numeric keys
_LOW = {"size": (16, False), "distance": (0, True), "gamma": (0, True), "vignette": (0, False),
        "hot_pixels": (0, False), "exposure": (0, True), "power_spread": (0, False),
        "read_noise": (0, False), "current": (0, True), "timeout": (0, True),
        "fault_after": (0, False), "baud": (0, True)}


def _parse(argv):
    args = {}
    for a in argv:
        if "=" not in a or a.startswith("-"):
            if a in ("-h", "--help"):
                print(__doc__)
                raise SystemExit(0)
            raise PsbenchError(f"argument {a!r}: expected key=value (see psbench-capture --help)")
        k, v = a.split("=", 1)
        args[k.strip()] = v.strip()
    return args


def _bool(v, key="value"):
    v = str(v).lower()
    if v not in ("1", "true", "yes", "on", "0", "false", "no", "off"):
        raise PsbenchError(f"{key}={v!r}: expected true or false")
    return v in ("1", "true", "yes", "on")


def _typed(args, key, typ, default=None, *, low=None, strict=False):
    """``args[key]`` (popped) converted to ``typ``, at least ``low`` (above it when
    ``strict``); a one-line error naming the key otherwise."""
    raw = args.pop(key, None)
    if raw is None:
        return default
    try:
        v = typ(raw)
    except (TypeError, ValueError):
        what = {int: "an integer", float: "a number"}.get(typ, typ.__name__)
        raise PsbenchError(f"{key}={raw!r}: expected {what}") from None
    if typ is float and v != v or v in (float("inf"), float("-inf")):
        raise PsbenchError(f"{key}={raw!r}: expected a finite number")
    if low is not None and (v <= low if strict else v < low):
        raise PsbenchError(f"{key}={raw!r}: expected a value {'>' if strict else '>='} {low}")
    return v


def default_out(rig, *, now=None):
    """The default capture folder: ``<results>/captures/<rig>_<UTC time>`` (a suffix
    ``-2``, ``-3``, ... when a capture of the same second exists)."""
    import datetime as _dt
    import os
    from pathlib import Path

    now = now or _dt.datetime.now(_dt.timezone.utc)
    root = Path(os.environ.get("PSBENCH_RESULTS") or "results").expanduser()  # as psbench's
    base = root / "captures" / f"{rig}_{now.strftime('%Y%m%dT%H%M%SZ')}"
    out, n = base, 2
    while out.exists():
        out, n = base.with_name(f"{base.name}-{n}"), n + 1
    return out


def main(argv=None):
    argv = sys.argv[1:] if argv is None else list(argv)
    restore = _stop_signals()
    try:
        args = _parse(argv)
        return _run(args)
    except KeyboardInterrupt as exc:
        why = _STOPPED.get("signal") or "SIGINT"
        state = getattr(exc, "led_state", None)
        leds = (f"LEDs off (STATE? {state})" if state is not None
                else "OFF sent to the LED controller")
        print(f"\npsbench-capture: interrupted ({why}); {leds}; partial output folder removed",
              file=sys.stderr)
        return 130
    except PsbenchError as e:
        print(f"psbench-capture: error: {e}", file=sys.stderr)
        return 2
    except OSError as e:                       # a device, a folder: the environment
        print(f"psbench-capture: error: {e.strerror or e}: {e.filename or ''}".rstrip(": "),
              file=sys.stderr)
        return 2
    finally:
        restore()


_STOPPED = {}


def _stop_signals():
    """SIGTERM and SIGHUP stop a capture as Ctrl-C does (KeyboardInterrupt: LEDs off,
    partial folder removed); a second signal during that cleanup is ignored. Returns
    the function restoring the previous handlers."""
    import signal
    import threading

    _STOPPED.clear()
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    sigs = [signal.SIGINT, signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])

    def stop(signum, frame):
        if _STOPPED:                           # cleaning up after the first one
            return
        _STOPPED["signal"] = signal.Signals(signum).name
        raise KeyboardInterrupt

    old = {s: signal.signal(s, stop) for s in sigs}

    def restore():
        for s, h in old.items():
            signal.signal(s, h)
    return restore


def _led_state(ctl, exc):
    """After an interruption: ask the controller (``STATE?``) what it lights now."""
    try:
        st = ctl.state()
        exc.led_state = " ".join(str(v) for v in (st if isinstance(st, (list, tuple)) else [st]))
    except Exception:  # noqa: BLE001 - the message says OFF was sent either way
        pass


def _clean_partials(out):
    from ..io._write import stale_partials

    for p in stale_partials(Path(out).expanduser().absolute().parent):
        print(f"psbench-capture: removed {p}, a partial folder left by a capture that was "
              "killed", file=sys.stderr)


def _run(args):
    from ..lights import layout
    from .controller import LedController
    from .sequence import capture, capture_all

    rig = args.pop("rig", "sim")
    if rig not in ("sim", "serial"):
        raise PsbenchError(f"rig={rig!r} is not known; valid choices: sim, serial")
    out = args.pop("out", None)
    if out is not None and not out.strip():
        raise PsbenchError("out='': expected a folder path (or leave out= away for the default)")
    if out is None:
        out = default_out(rig)
    lights = args.pop("lights", "30x4+60x4")
    current = _typed(args, "current", int, 350, low=0, strict=True)
    progress = _bool(args.pop("progress", "true"), "progress")
    overwrite = _bool(args.pop("overwrite", "false"), "overwrite")
    if rig == "sim":
        from .sim import RigConfig, SimController, SimRig
        kw = {}
        for k, typ in _SIM_KEYS.items():
            if k in args:
                lo, strict = _LOW.get(k, (None, False))
                kw[k] = _typed(args, k, typ, low=lo, strict=strict)
        targets = args.pop("targets", "all")
        fault = args.pop("fault", None)
        after = _typed(args, "fault_after", int, 0, low=0)
        timeout = _typed(args, "timeout", float, 1.0, low=0, strict=True)
        if args:
            raise PsbenchError(f"unknown key(s) for rig=sim: {', '.join(args)}")
        simrig = SimRig(RigConfig(lights=lights, current_mA=current, **kw))
        tlist = () if targets == "none" else (("sphere", "white", "chart", "grid")
                                              if targets == "all" else tuple(targets.split(",")))
        _clean_partials(out)
        with SimController(simrig.k, fault=fault, after=after) as dev:
            with LedController(dev.port, timeout=timeout) as ctl:
                try:
                    path = capture_all(simrig, ctl, out, device=dev, progress=progress,
                                       overwrite=overwrite, targets=tlist)
                except KeyboardInterrupt as exc:
                    _led_state(ctl, exc)
                    raise
        print(path)
        return 0
    from .camera import FolderCamera, OpenCVCamera
    port = args.pop("port", None)
    if not port:
        raise PsbenchError("rig=serial needs port=/dev/ttyUSB0 (or COMn)")
    cam_arg = args.pop("camera", "0")
    exposure = args.pop("exposure", None)
    baud = _typed(args, "baud", int, 115200, low=0, strict=True)
    timeout = _typed(args, "timeout", float, 1.0, low=0, strict=True)
    target = args.pop("target", "object")
    leds = args.pop("leds", None)
    if args:
        raise PsbenchError(f"unknown key(s) for rig=serial: {', '.join(args)}")
    lay = layout(lights)
    try:
        led_idx = None if leds is None else [int(x) for x in leds.split(",")]
    except ValueError:
        raise PsbenchError(f"leds={leds!r}: expected comma-separated LED numbers, e.g. 3,4,5") from None
    _clean_partials(out)
    with LedController(port, baudrate=baud, timeout=timeout) as ctl:
        cam = OpenCVCamera(int(cam_arg), exposure=None if exposure is None else float(exposure)) \
            if cam_arg.isdigit() else FolderCamera(cam_arg)
        cam.open()
        try:
            path = capture(ctl, cam, out, lay, current_mA=current, leds=led_idx,
                           meta={"rig": "serial", "target": target, "exposure": exposure},
                           progress=progress, overwrite=overwrite)
        except KeyboardInterrupt as exc:
            _led_state(ctl, exc)
            raise
        finally:
            cam.close()
    print(path)
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
