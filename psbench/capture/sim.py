"""Simulated rig: a PSLED controller on a pseudo-terminal and a virtual camera.

:class:`SimController` opens a pty pair (``os.openpty``), puts it in raw mode and
serves the PSLED protocol (:mod:`psbench.capture.protocol`) on the master side
from a background thread. The driver (:class:`psbench.capture.controller.LedController`)
opens the slave by name with ``serial.Serial`` -- real serial I/O through the
kernel's tty layer, not a mock. Faults can be injected after ``after`` commands:

- ``"silence"``    the device keeps executing commands but never replies (broken TX)
- ``"garbage"``    the device executes commands and replies with garbage bytes
- ``"disconnect"`` the device disappears (master closed: the host sees EIO/hang-up);
                   like a USB-powered controller losing power, its LEDs go dark
- ``"error"``      internal fault: the firmware shuts all LEDs off and replies
                   ``ERR 5 internal fault`` to every command

The controller records its LED currents (``.leds``), every command (``.log``) and
whether it is still connected, so tests can check that a capture left the LEDs off.

:class:`SimRig` is the physical scene: LEDs at finite distance (``distance`` pixels
from the origin along the nominal layout directions, each with its own power),
and a :class:`SimCamera` that renders what it sees under the LEDs the controller
currently drives (:func:`psbench.render` with ``light_positions`` and inverse-square
``falloff``), then applies the camera's imperfections: a smooth radial vignette,
hot pixels at fixed seeded positions, read noise, a non-linear response
``out = E ** (1 / gamma)`` and 8-bit quantisation. It also shows the calibration
targets: a specular sphere (``sphere``), a white Lambertian plane (``white``), a
9-step transmissive gray wedge on a uniform light box (``chart``, LEDs irrelevant),
a backlit grid of known pitch (``grid``) and nothing (``dark`` = lens cap).
:meth:`SimRig.ideal` renders the calibration-free reference: distant lights along
the true directions, unit power, linear, no vignette, no hot pixels, float.
"""
from __future__ import annotations

import os
import select
import threading
import time
import tty
from dataclasses import dataclass

import numpy as np

from .._shared.checks import PsbenchError, choice
from .protocol import (ERR_ARGS, ERR_CURRENT, ERR_FAULT, ERR_INDEX, ERR_UNKNOWN, ERROR_TEXT,
                       parse_command)

__all__ = ["SimController", "SimRig", "SimCamera", "RigConfig", "FAULTS", "TARGETS"]

FAULTS = (None, "silence", "garbage", "disconnect", "error")
TARGETS = ("object", "sphere", "white", "chart", "grid", "dark")


class SimController:
    """A virtual PSLED controller served on a pseudo-terminal.

    Parameters
    ----------
    n_leds : int
    firmware : str
    max_mA : int
    fault : {None, "silence", "garbage", "disconnect", "error"}
    after : int
        Number of commands answered normally before the fault starts.
    reply_delay : float
        Seconds to wait before each reply.

    Attributes
    ----------
    port : str
        Slave device name to open with ``serial.Serial``.
    leds : (n_leds,) int array
        Current of each LED in mA (the device state).
    log : list of str
        Commands received.
    connected : bool
    """

    def __init__(self, n_leds=8, *, firmware="sim-1.0", max_mA=1000, fault=None, after=0,
                 reply_delay=0.0):
        choice(fault, FAULTS, "fault")
        self.n_leds = int(n_leds)
        self.firmware = firmware
        self.max_mA = int(max_mA)
        self.fault = fault
        self.after = int(after)
        self.reply_delay = float(reply_delay)
        self.leds = np.zeros(self.n_leds, dtype=int)
        self.log = []
        self.connected = False
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self._master = self._slave = None
        self.port = None

    # -- lifecycle
    def start(self):
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        tty.setraw(self._master)
        self.port = os.ttyname(self._slave)
        self.connected = True
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, name="psled-sim", daemon=True)
        self._thread.start()
        return self

    def stop(self):
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        self._close_master()
        if self._slave is not None:
            try:
                os.close(self._slave)
            except OSError:
                pass
            self._slave = None

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
        return False

    @property
    def all_off(self) -> bool:
        return not self.leds.any()

    def _close_master(self):
        if self._master is not None:
            try:
                os.close(self._master)
            except OSError:
                pass
            self._master = None
        self.connected = False

    # -- device
    def _serve(self):
        buf = b""
        while not self._stop.is_set() and self._master is not None:
            try:
                r, _, _ = select.select([self._master], [], [], 0.02)
            except (OSError, ValueError):
                break
            if not r:
                continue
            try:
                data = os.read(self._master, 1024)
            except OSError:
                time.sleep(0.01)
                continue
            if not data:
                continue
            buf += data
            while b"\n" in buf:
                raw, buf = buf.split(b"\n", 1)
                reply = self._handle(raw.decode("ascii", "replace").strip())
                if self._master is None:
                    return
                if reply is not None:
                    if self.reply_delay:
                        time.sleep(self.reply_delay)
                    try:
                        os.write(self._master, reply)
                    except OSError:
                        pass

    def _execute(self, line):
        try:
            name, args = parse_command(line)
        except KeyError:
            return f"ERR {ERR_UNKNOWN} {ERROR_TEXT[ERR_UNKNOWN]}"
        except ValueError as e:
            return f"ERR {ERR_ARGS} {e}"
        with self._lock:
            if name == "ID?":
                return f"PSLED {self.n_leds} {self.firmware}"
            if name == "OFF":
                self.leds[:] = 0
                return "OK"
            if name == "STATE?":
                return "STATE " + " ".join(str(int(v)) for v in self.leds)
            if name == "MAX?":
                return f"MAX {self.max_mA}"
            i, mA = args
            if not 0 <= i < self.n_leds:
                return f"ERR {ERR_INDEX} {ERROR_TEXT[ERR_INDEX]}: {i} not in 0..{self.n_leds - 1}"
            if not 0 <= mA <= self.max_mA:
                return f"ERR {ERR_CURRENT} {ERROR_TEXT[ERR_CURRENT]}: {mA} not in 0..{self.max_mA}"
            self.leds[i] = mA
            return "OK"

    def _handle(self, line):
        self.log.append(line)
        faulty = self.fault is not None and len(self.log) > self.after
        if faulty and self.fault == "disconnect":
            with self._lock:
                self.leds[:] = 0  # power lost with the connection
            self._close_master()
            return None
        if faulty and self.fault == "error":
            with self._lock:
                self.leds[:] = 0  # protective shutdown on an internal fault
            return f"ERR {ERR_FAULT} {ERROR_TEXT[ERR_FAULT]}\n".encode()
        reply = self._execute(line)
        if faulty and self.fault == "silence":
            return None
        if faulty and self.fault == "garbage":
            return b"\xfe\x13#%@!K\x00~?\n"
        return (reply + "\n").encode("ascii")


@dataclass
class RigConfig:
    """Parameters of the simulated rig.

    size : image side (pixels); surface : psbench surface name; lights : ring notation
    of the nominal LED layout; distance : LED distance from the origin in pixels
    (default 6 x size); power_spread : LED powers uniform in 1 +- spread (seeded);
    current_mA : nominal current (images scale linearly with current / nominal);
    exposure : linear gain; vignette : fall-off at the image corner (V = 1 - v r^2,
    r = 1 at the corner); gamma : response out = E^(1/gamma) (1 = linear);
    hot_pixels : count; read_noise : sigma in linear units; bits : output depth;
    model : render model of the object; sphere_m : Phong exponent of the sphere;
    pixel_mm : pixel size (mm) for the grid; grid_mm : grid pitch (mm);
    misplace_deg : LEDs deviate from the nominal directions by about this (seeded).
    """

    size: int = 128
    surface: str = "penny"
    lights: str = "30x4+60x4"
    distance: float | None = None
    power_spread: float = 0.15
    current_mA: int = 350
    exposure: float = 0.9
    vignette: float = 0.3
    gamma: float = 2.2
    hot_pixels: int = 12
    read_noise: float = 0.001
    bits: int = 8
    model: str = "lambert"
    albedo: float = 0.8
    sphere_m: float = 400.0
    pixel_mm: float = 0.0932
    grid_mm: float = 1.0
    misplace_deg: float = 1.5
    seed: int = 0

    @classmethod
    def ideal(cls, **kw):
        """A rig without imperfections (linear, no vignette, no hot pixels, equal powers,
        far lights, no noise) -- for checking the calibration steps one at a time."""
        base = dict(distance=1e6, power_spread=0.0, misplace_deg=0.0, vignette=0.0, gamma=1.0, hot_pixels=0,
                    read_noise=0.0)
        base.update(kw)
        return cls(**base)


class SimRig:
    """A simulated photometric-stereo rig (LED geometry, scene, camera imperfections).

    Parameters
    ----------
    config : RigConfig, optional
    **kw : overrides of RigConfig fields
    """

    def __init__(self, config=None, **kw):
        from ..lights import layout

        cfg = config or RigConfig()
        for key, v in kw.items():
            if not hasattr(cfg, key):
                raise PsbenchError(f"unknown rig option {key!r}; valid: {', '.join(RigConfig.__dataclass_fields__)}")
            setattr(cfg, key, v)
        self.config = cfg
        self.nominal = layout(cfg.lights)
        k = self.nominal.k
        self.k = k
        s = cfg.size
        dist = float(cfg.distance) if cfg.distance is not None else 6.0 * s
        self.distance = dist
        rng = np.random.default_rng(cfg.seed)
        # true LED positions: nominal directions, slightly misplaced (+-1.5 deg), at `dist`
        d = self.nominal.directions + rng.normal(0, np.radians(cfg.misplace_deg), (k, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        self.positions = d * dist
        self.directions = d
        self.powers = 1.0 + cfg.power_spread * rng.uniform(-1, 1, k)
        H = W = s
        x = np.arange(W) - (W - 1) / 2
        y = (H - 1) / 2 - np.arange(H)
        r2 = (x[None, :] ** 2 + y[:, None] ** 2) / (((W - 1) / 2) ** 2 * 2)
        self.vignette = (1.0 - cfg.vignette * r2).astype(np.float32)
        hot = np.zeros(H * W, dtype=np.float32)
        idx = rng.choice(H * W, size=cfg.hot_pixels, replace=False) if cfg.hot_pixels else []
        hot[idx] = rng.uniform(0.3, 0.9, len(idx))
        self.hot = hot.reshape(H, W)
        self.hot_mask = self.hot > 0
        self._cache = {}
        self.frames = 0
        from ..surfaces import make_surface
        self.surface = make_surface(cfg.surface, size=s)
        # chart: 9 patches on a circle (equal vignette), radiances 0.1 .. 0.9
        self.chart_radiance = np.linspace(0.1, 0.9, 9)
        rad = 0.3 * s
        half = max(2, int(0.05 * s))
        boxes = []
        for j in range(9):
            a = 2 * np.pi * j / 9
            cx = int(round((W - 1) / 2 + rad * np.cos(a)))
            cy = int(round((H - 1) / 2 - rad * np.sin(a)))
            boxes.append((cy - half, cy + half + 1, cx - half, cx + half + 1))
        self.chart_boxes = boxes

    # -- linear radiance seen by the camera (before vignette) for each LED at unit current
    def _stack(self, target):
        if target in self._cache:
            return self._cache[target]
        from ..render.scene import render
        from ..surfaces import surface_from_height, make_surface
        cfg = self.config
        s = cfg.size
        if target == "object":
            out = render(self.surface, self.directions, model=cfg.model, rho_d=cfg.albedo,
                         light_positions=self.positions, falloff=True, shadows=True).images
        elif target == "white":
            plane = surface_from_height(np.zeros((s, s)))
            out = render(plane, self.directions, model="lambert", rho_d=cfg.albedo,
                         light_positions=self.positions, falloff=True, shadows=False).images
        elif target == "sphere":
            sph = make_surface("semisphere_disc", size=s)
            out = render(sph, self.directions, model="phong", phong_m=cfg.sphere_m, rho_d=0.03,
                         rho_s=1.0, light_positions=self.positions, falloff=True,
                         shadows=False).images
        else:
            out = None
        if out is not None:
            out = out * self.powers[:, None, None].astype(np.float32)
        self._cache[target] = out
        return out

    def radiance(self, target, currents):
        """Linear irradiance at the sensor (H, W) for LED currents (n,) mA, vignette applied."""
        cfg = self.config
        s = cfg.size
        choice(target, TARGETS, "target")
        if target == "chart":
            img = np.zeros((s, s), dtype=np.float32)
            for r, (a, b, c, d) in zip(self.chart_radiance, self.chart_boxes):
                img[a:b, c:d] = r
        elif target == "grid":
            period = cfg.grid_mm / cfg.pixel_mm
            x = np.arange(s) - (s - 1) / 2
            dx = np.abs((x / period + 0.5) % 1.0 - 0.5) * period
            line = np.exp(-0.5 * (dx / 0.8) ** 2)
            img = (0.8 - 0.6 * np.maximum(line[None, :], line[:, None])).astype(np.float32)
        elif target == "dark":
            img = np.zeros((s, s), dtype=np.float32)
        else:
            stack = self._stack(target)
            w = np.asarray(currents, dtype=np.float32)[: self.k] / np.float32(cfg.current_mA)
            img = np.tensordot(w, stack, axes=1).astype(np.float32) if w.any() \
                else np.zeros((s, s), np.float32)
        return img * self.vignette

    def expose(self, linear, *, seed=None):
        """Camera model: gain, hot pixels, noise, response, quantisation -> uint8/16 (H, W)."""
        cfg = self.config
        rng = np.random.default_rng(cfg.seed * 1000003 + (self.frames if seed is None else seed))
        e = linear * np.float32(cfg.exposure) + self.hot
        if cfg.read_noise:
            e = e + rng.normal(0.0, cfg.read_noise, e.shape).astype(np.float32)
        e = np.clip(e, 0.0, 1.0)
        out = e ** np.float32(1.0 / cfg.gamma)
        top = 2 ** cfg.bits - 1
        q = np.round(out * top)
        self.frames += 1
        return q.astype(np.uint8 if cfg.bits <= 8 else np.uint16)

    def response(self, e):
        """The camera's response curve (for tests): linear exposure -> [0, 1] output."""
        return np.clip(e, 0, 1) ** (1.0 / self.config.gamma)

    def ideal(self, *, model=None, shadows=True):
        """Calibration-free reference images of the object: distant lights along the
        true directions, unit power, linear, no vignette/hot pixels, float."""
        from ..render.scene import render
        from ..lights import layout
        cfg = self.config
        sc = render(self.surface, layout(self.directions, ring=self.nominal.ring),
                    model=model or cfg.model, rho_d=cfg.albedo, shadows=shadows)
        return sc

    def true_layout(self):
        from ..lights import layout
        return layout(self.directions, power=self.powers, ring=self.nominal.ring,
                      positions=self.positions)

    def camera(self, controller, target="object", **kw):
        return SimCamera(self, controller, target=target, **kw)


class SimCamera:
    """Virtual camera of a :class:`SimRig`: sees ``target`` lit by the LEDs that
    ``controller`` (a :class:`SimController`) currently drives.

    Parameters
    ----------
    rig : SimRig
    controller : SimController
        The device whose LED state lights the scene.
    target : str
        One of :data:`TARGETS`; can be changed between captures.
    callback : callable(frame_index), optional
        Called before each frame (tests raise KeyboardInterrupt from it).
    """

    name = "sim"

    def __init__(self, rig, controller, *, target="object", callback=None):
        self.rig = rig
        self.controller = controller
        self.target = choice(target, TARGETS, "target")
        self.callback = callback
        self.bits = rig.config.bits
        self.count = 0

    def open(self):
        return self

    def grab(self):
        """One frame, (H, W) uint8 (or uint16 for bits > 8)."""
        if self.callback is not None:
            self.callback(self.count)
        self.count += 1
        with self.controller._lock:
            currents = self.controller.leds.copy()
        return self.rig.expose(self.rig.radiance(self.target, currents))

    def close(self):
        pass

    def describe(self):
        return {"camera": "sim", "bits": self.bits, "target": self.target}
