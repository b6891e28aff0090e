"""A procedural fired cartridge case, seen from below (thesis Chapter 7, Figs. 7.1-7.3).

:func:`make_cartridge` builds the head of a 9 mm-class centre-fire case after firing, in
micrometres on a square pixel grid (default 4.9 µm per pixel at 2048², the thesis's
10 mm field of view, at any size):

- the **case head**: a disc of 9.5 mm with a bevelled (chamfered) rim, a slight bulge,
  the case's own machining texture and stamped **headstamp** letters;
- the **primer cup**, seated below the head face, with its pocket gap;
- the **firing-pin impression**: a concave crater a few hundred µm wide and 140-240 µm
  deep with steep (60-75°) walls and a raised lip, its bottom marked by the firing
  pin's tip;
- the **breech-face impressions** on the primer face: filed striations, turning arcs,
  granular texture, long scratches and dents of a few µm;
- an **ejector mark** near the rim.

Two seeds drive it. ``gun`` fixes the gun's marks (breech face, firing-pin shape and tip
marks, ejector position and size), generated on a gun grid of fixed spacing
(:mod:`psbench.forensic._fields`) so the marks do not depend on the image's pixel size.
``case`` (together with ``gun``) fixes the case's own variation: its position and
orientation in the holder, its orientation in the chamber (the gun's frame), the
chamber play, how deep and how completely the marks were impressed, the primer seating,
the metal finish, the case texture and albedo blotches. ``gun=3, case=5`` is therefore
a *sister* of ``gun=3, case=3``; ``gun=4`` is a different gun. Everything is
deterministic per (gun, case, size, pixel_size).

psbench renders in pixel units: :class:`Cartridge` holds ``height`` in pixels (what
:func:`psbench.render` needs) and :attr:`Cartridge.height_um` in µm (what the forensic
metrics need), plus ``pixel_size`` and the ground-truth ``regions``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping

import cv2
import numpy as np

from .._shared.checks import PsbenchError
from ..surfaces import Surface
from . import _fields as F

__all__ = ["Cartridge", "make_cartridge", "REGIONS", "FINISHES", "CASE_DIAMETER",
           "PRIMER_RADIUS", "DEFAULT_PIXEL_SIZE", "MAX_PIXEL_SIZE", "check_pixel_size",
           "check_seed"]

#: diameter of the case head (µm)
CASE_DIAMETER = 9500.0
#: radius of the primer cup (µm; small pistol primer)
PRIMER_RADIUS = 2225.0
#: pixel size (µm) at 2048 x 2048, the thesis's 10 mm field of view (Section 7)
DEFAULT_PIXEL_SIZE = 4.9
#: coarsest pixel (µm) that still holds the features (firing pin >= ~14 px across its
#: radius, breech-face marks up to the 250 µm cut-off >= ~6 px per wavelength)
MAX_PIXEL_SIZE = 40.0
#: ground-truth region names of :attr:`Cartridge.regions`
REGIONS = ("case", "bevel", "headstamp", "primer", "breech_face", "firing_pin",
           "firing_pin_wall", "ejector")
#: metal finishes a case may have (rendering presets in :mod:`psbench.forensic.presets`)
FINISHES = ("brass", "nickel")

_HEADSTAMPS = (("AKX", "9mm LUGER"), ("RTM", "9x19"), ("PSB", "9 mm"), ("HXT", "LUGER"),
               ("NRV", "9mm PARA"), ("KLS", "9x19 NATO"))
_BEVEL_W, _BEVEL_H = 220.0, 180.0          # chamfer width and drop (µm)
_BACKGROUND = -700.0                       # holder level below the head face (µm)
_TEXT_R, _TEXT_H, _TEXT_STROKE, _TEXT_DEPTH = 3450.0, 800.0, 110.0, 60.0
_WALL_SLOPE = 30.0                         # firing-pin wall: surface zenith above this (deg)
_f32 = np.float32


@dataclass(frozen=True, eq=False)
class Cartridge(Surface):
    """A cartridge-case surface: a :class:`psbench.Surface` with forensic ground truth.

    Attributes
    ----------
    name, height, object_mask, normals
        As :class:`psbench.Surface`: ``height`` (H, W) float32 in **pixel units**,
        ``object_mask`` (H, W) bool the case head (the object), ``normals`` (H, W, 3).
    pixel_size : float
        Micrometres per pixel.
    gun, case : int
        The seeds.
    finish : str
        Metal finish of the case, one of :data:`FINISHES`.
    albedo : (H, W) float32
        Relative diffuse albedo (mean ~1): tarnish blotches, the primer's own alloy.
    regions : mapping of str to (H, W) bool
        Ground truth, keys :data:`REGIONS`: ``case`` (= object_mask), ``bevel``, ``headstamp``
        (letters), ``primer``, ``breech_face`` (primer face carrying the breech-face
        marks, firing pin excluded: the comparison region), ``firing_pin`` (impression,
        walls and lip), ``firing_pin_wall`` (its walls steeper than 30°), ``ejector``.
    pose : mapping of str to float
        The case's variation: ``case_x``, ``case_y`` (µm, case centre from the image
        centre), ``case_angle`` (deg, headstamp orientation), ``gun_x``, ``gun_y`` (µm,
        firing-pin centre), ``gun_angle`` (deg, the gun's frame in the image),
        ``depth_scale``, ``primer_seat`` (µm), ``tilt`` and ``tilt_azimuth`` (deg).
    """

    pixel_size: float = DEFAULT_PIXEL_SIZE
    gun: int = 0
    case: int = 0
    finish: str = "brass"
    albedo: np.ndarray | None = None
    regions: Mapping[str, np.ndarray] = field(default_factory=dict)
    pose: Mapping[str, float] = field(default_factory=dict)

    def __post_init__(self):
        # the base class validates and freezes name, height, object_mask and normals
        Surface.__init__(self, self.name, self.height, self.object_mask, self.normals)
        regions = {}
        for key, m in dict(self.regions).items():
            m = np.array(m, dtype=bool, copy=True)
            if m.shape != self.shape:
                raise PsbenchError(f"regions[{key!r}] must have shape {self.shape}, got {m.shape}")
            m.setflags(write=False)
            regions[key] = m
        albedo = np.ones(self.shape, np.float32) if self.albedo is None else \
            np.array(self.albedo, dtype=np.float32, copy=True)
        if albedo.shape != self.shape:
            raise PsbenchError(f"albedo must have shape {self.shape}, got {albedo.shape}")
        albedo.setflags(write=False)
        object.__setattr__(self, "regions", MappingProxyType(regions))
        object.__setattr__(self, "albedo", albedo)
        object.__setattr__(self, "pose", MappingProxyType(dict(self.pose)))
        object.__setattr__(self, "pixel_size", check_pixel_size(self.pixel_size))

    @property
    def height_um(self):
        """(H, W) float32 heights in micrometres."""
        return self.height * np.float32(self.pixel_size)

    def __repr__(self):
        return (f"Cartridge(gun={self.gun}, case={self.case}, shape={self.shape}, "
                f"pixel_size={self.pixel_size:g} um, finish={self.finish!r})")


# ----------------------------------------------------------------------------- checks
def check_pixel_size(pixel_size, name="pixel_size"):
    """A finite float > 0 (µm per pixel), else a one-line error naming ``name``."""
    try:
        v = float(pixel_size)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be a number of micrometres > 0, "
                           f"got {pixel_size!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise PsbenchError(f"{name} must be a finite number of micrometres > 0, got {pixel_size!r}")
    return v


def check_seed(value, name):
    """A non-negative integer seed (bools and floats refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < 0:
        raise PsbenchError(f"{name} must be a non-negative integer seed, got {value!r}")
    return int(value)


def _check(size, gun, case, pixel_size, finish):
    if isinstance(size, (bool, np.bool_)) or not isinstance(size, (int, np.integer)) or size < 2:
        raise PsbenchError(f"size must be an integer number of pixels, got {size!r}")
    size = int(size)
    gun, case = check_seed(gun, "gun"), check_seed(case, "case")
    ps = DEFAULT_PIXEL_SIZE * 2048 / size if pixel_size is None else check_pixel_size(pixel_size)
    if ps > MAX_PIXEL_SIZE:
        need = math.ceil(2048 * DEFAULT_PIXEL_SIZE / MAX_PIXEL_SIZE)
        raise PsbenchError(
            f"size={size} with pixel_size={ps:.3g} um is too coarse for the cartridge's "
            f"features: pixel_size must be <= {MAX_PIXEL_SIZE:g} um (size >= {need} at the "
            f"default 10 mm field of view)")
    if size * ps < CASE_DIAMETER + 8 * ps:
        raise PsbenchError(
            f"size={size} x pixel_size={ps:.3g} um = {size * ps:.0f} um cannot hold the "
            f"{CASE_DIAMETER:.0f} um case head; raise size or pixel_size")
    if finish is not None and finish not in FINISHES:
        raise PsbenchError(f"finish={finish!r} is not known; valid choices: {', '.join(FINISHES)}")
    return size, gun, case, ps


# ----------------------------------------------------------------------------- parts
def _soft(d, w):
    """0 -> 1 step across d = 0 of half width ~w (tanh)."""
    return 0.5 * (1.0 + np.tanh(d / np.float32(w)))


def _rotate(x, y, angle):
    c, s = np.float32(math.cos(angle)), np.float32(math.sin(angle))
    return c * x + s * y, -s * x + c * y            # coordinates in a frame rotated by angle


def _normals(height):
    """Unit normals by central differences (as :func:`psbench.surfaces.normals_from_height`),
    in float32: (H, W, 3)."""
    d_row, d_col = np.gradient(height.astype(np.float32))
    n = np.empty(height.shape + (3,), np.float32)
    inv = 1.0 / np.sqrt(1.0 + d_col * d_col + d_row * d_row)
    np.multiply(-d_col, inv, out=n[..., 0])
    np.multiply(d_row, inv, out=n[..., 1])
    n[..., 2] = inv
    return n


def _coarse_field(rng, size, lo_frac, shape_out):
    """Smooth unit-RMS random field (features ~``lo_frac`` of the frame) at ``shape_out``."""
    n = 96
    f = F.band(rng, n, 1.0, lo_frac * n, 4.0 * lo_frac * n)
    return cv2.resize(f, shape_out[::-1], interpolation=cv2.INTER_CUBIC)


def _headstamp(xc, yc, rho, texts, ps):
    """Letter coverage in [0, 1]: ``texts`` = (top, bottom) strings around the ring."""
    font = cv2.FONT_HERSHEY_SIMPLEX
    h1 = cv2.getTextSize("X", font, 1.0, 1)[0][1]
    cap = _TEXT_H / ps
    scale = cap / h1
    thick = max(1, int(round(_TEXT_STROKE / ps)))
    phi = np.arctan2(yc, xc)
    out = np.zeros(rho.shape, np.float32)
    pi, tau = np.float32(np.pi), np.float32(2 * np.pi)
    for text, centre, sign in ((texts[0], math.pi / 2, -1.0), (texts[1], -math.pi / 2, 1.0)):
        (w, h), base = cv2.getTextSize(text, font, scale, thick)
        pad = thick + 2
        strip = np.zeros((h + base + 2 * pad, w + 2 * pad), np.uint8)
        cv2.putText(strip, text, (pad, pad + h), font, scale, 255, thick, cv2.LINE_AA)
        # letter spacing grows with the arc: the strip's columns are arc length at _TEXT_R
        dphi = (phi - np.float32(centre) + pi) % tau - pi
        col = sign * dphi * np.float32(_TEXT_R / ps) + np.float32(strip.shape[1] / 2)
        if sign < 0:   # top: letter tops point outwards
            row = (np.float32(_TEXT_R + _TEXT_H / 2) - rho) / np.float32(ps) + np.float32(pad)
        else:          # bottom: letter tops point inwards (upright in the image)
            row = (rho - np.float32(_TEXT_R - _TEXT_H / 2)) / np.float32(ps) + np.float32(pad)
        cov = cv2.remap(strip.astype(np.float32) / 255.0, col.astype(np.float32),
                        row.astype(np.float32), cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        np.maximum(out, cov, out=out)
    return out


def make_cartridge(size=2048, *, gun=0, case=0, pixel_size=None, finish=None):
    """A fired cartridge case's head (see the module docstring).

    Parameters
    ----------
    size : int, default 2048
        Side of the square (size, size) grid.
    gun : int, default 0
        Seed of the gun (its breech face, firing pin and ejector), >= 0.
    case : int, default 0
        Seed of the case's own variation (with ``gun``), >= 0.
    pixel_size : float, optional
        Micrometres per pixel, > 0. Default ``4.9 * 2048 / size``: the thesis's 10 mm
        field of view at any size. The field of view must hold the 9.5 mm head and
        the pixel must not exceed :data:`MAX_PIXEL_SIZE` (40 µm).
    finish : {"brass", "nickel"}, optional
        Override the case's metal finish (default: drawn from the case seed, brass 70 %).

    Returns
    -------
    Cartridge
        ``height`` in pixel units, ``height_um``, ``mask`` (the case head), ``normals``,
        ``regions``, ``albedo``, ``pose``. Deterministic per arguments.
    """
    size, gun, case, ps = _check(size, gun, case, pixel_size, finish)
    gm = F.gun_marks(gun)
    rng = np.random.default_rng([0xCA5E, gun, case])
    pose = {
        "case_x": float(rng.uniform(-150, 150)), "case_y": float(rng.uniform(-150, 150)),
        "case_angle": float(rng.uniform(0, 360)), "gun_angle": float(rng.uniform(0, 360)),
        "depth_scale": float(rng.uniform(0.8, 1.1)), "primer_seat": float(rng.uniform(20, 60)),
        "tilt": 0.0, "tilt_azimuth": 0.0,
    }
    play = rng.uniform(-60, 60, 2)
    pose["gun_x"], pose["gun_y"] = pose["case_x"] + float(play[0]), pose["case_y"] + float(play[1])
    chosen = finish or ("brass" if rng.uniform() < 0.7 else "nickel")
    texts = _HEADSTAMPS[int(rng.integers(len(_HEADSTAMPS)))]
    fp_scale = float(rng.uniform(0.9, 1.05))
    lip_scale = float(rng.uniform(0.5, 1.5))
    aa = 0.6 * ps                                   # no step narrower than ~a pixel

    x, y = F.grid_xy(size, ps)
    R, Rp = CASE_DIAMETER / 2, PRIMER_RADIUS
    dx, dy = x - _f32(pose["case_x"]), y - _f32(pose["case_y"])
    rho = np.sqrt(dx * dx + dy * dy)
    xc, yc = _rotate(dx, dy, math.radians(pose["case_angle"]))
    xg, yg = _rotate(x - _f32(pose["gun_x"]), y - _f32(pose["gun_y"]),
                     math.radians(pose["gun_angle"]))
    rg = np.sqrt(xg * xg + yg * yg)

    # head: flat face with a slight bulge, chamfer, holder far below
    z = _f32(2.0) * (1.0 - (rho / _f32(R)) ** 2)
    z = z - _f32(_BEVEL_H) * F.smoothstep((rho - _f32(R - _BEVEL_W)) / _f32(_BEVEL_W))
    z = np.where(rho < R, z, _f32(_BACKGROUND)).astype(np.float32)
    # case texture: fine isotropic roughness and its own turning marks
    tex = F.band(rng, size, ps, max(14.0, 2.0 * ps), 150.0)
    turn = np.cos(_f32(2 * np.pi / rng.uniform(40, 90)) * rho + _f32(rng.uniform(0, 6.3)))
    # headstamp letters, stamped into the head face
    letters = _headstamp(xc, yc, rho, texts, ps)
    letters = cv2.GaussianBlur(letters, (0, 0), sigmaX=max(15.0 / ps, 0.5))
    z -= _f32(_TEXT_DEPTH) * letters
    # primer: seated below the face, rounded cup edge, pocket gap
    in_primer = _soft(_f32(Rp) - rho, max(8.0, aa))
    primer_z = -_f32(pose["primer_seat"]) \
        - _f32(25.0) * F.smoothstep((rho - _f32(Rp - 90)) / _f32(90))
    z = z * (1 - in_primer) + primer_z * in_primer
    z -= _f32(60.0) * np.exp(-((rho - _f32(Rp + 15)) / _f32(max(15.0, aa))) ** 2)
    # firing-pin impression (gun frame)
    bowl, u, lip_u = _firing_pin(rg, gm, pose["depth_scale"] * fp_scale, lip_scale, aa)
    z += bowl * in_primer
    # the gun's marks, impressed with this case's depth and a patchy transfer
    face = 1.0 - F.smoothstep((rho - _f32(Rp - 160)) / _f32(100))
    transfer = np.clip(0.7 + 0.35 * _coarse_field(rng, size, 0.08, (size, size)), 0.3, 1.0)
    w_bf = face * F.smoothstep((u - _f32(lip_u + 0.05)) / _f32(0.2)) * transfer
    w_tip = 1.0 - F.smoothstep((u - _f32(0.55)) / _f32(0.3))
    marks = w_bf * F.sample(gm["breech"], xg, yg, spacing=F.GUN_SPACING, pixel_size=ps) \
        + w_tip * F.sample(gm["tip"], xg, yg, spacing=F.GUN_SPACING, pixel_size=ps)
    z += _f32(pose["depth_scale"]) * marks
    # ejector mark near the rim (gun frame)
    box, striae = _ejector(xg, yg, gm, R, aa)
    z -= _f32(pose["depth_scale"]) * box * (_f32(gm["ejector_depth"]) + 1.5 * striae)
    # the case's own texture (less on the primer, whose face took the breech's)
    head = (1 - in_primer) * (rho < R)
    z += (0.3 + 0.3 * head) * tex + 0.3 * head * turn

    case_mask = rho < _f32(R - ps)
    height = np.where(case_mask, z, np.minimum(z, _f32(_BACKGROUND))) / _f32(ps)
    normals = _normals(height)
    zen = np.degrees(np.arccos(np.clip(normals[..., 2], -1, 1)))
    fp = (u < _f32(lip_u + 0.1)) & (rho < Rp)
    regions = {
        "case": case_mask,
        "bevel": case_mask & (rho > _f32(R - _BEVEL_W)),
        "headstamp": case_mask & (letters > 0.5),
        "primer": rho < _f32(Rp),
        "breech_face": (rho < _f32(Rp - 160)) & (u > _f32(lip_u + 0.25)),
        "firing_pin": fp,
        "firing_pin_wall": fp & (zen > _WALL_SLOPE) & (u > 0.6),
        "ejector": case_mask & (box > 0.5),
    }
    albedo = 1.0 + 0.08 * _coarse_field(rng, size, 0.15, (size, size))
    albedo = albedo * np.where(regions["primer"], _f32(rng.uniform(0.8, 1.1)), _f32(1.0))
    return Cartridge(name=f"cartridge(gun={gun},case={case})", height=height, object_mask=case_mask,
                     normals=normals, pixel_size=ps, gun=gun, case=case, finish=chosen,
                     albedo=albedo.astype(np.float32), regions=regions, pose=pose)


def _firing_pin(rg, gm, depth_scale, lip_scale, aa):
    """Concave impression at gun-frame radius ``rg`` (µm): a bowl ``-D (1 - c u²)`` with
    tanh walls of the gun's wall angle and a raised lip; returns (heights, u, lip_u)."""
    Rf, Df, c = gm["fp_radius"], gm["fp_depth"] * depth_scale, gm["fp_curv"]
    # tanh half width (in u = r / Rf) giving the wall angle at u = 1, never under a pixel
    w = max(Df * (1 - c) / (2 * Rf * math.tan(math.radians(gm["fp_wall"]))), aa / Rf)
    u = rg / _f32(Rf)
    bowl = -_f32(Df) * (1 - _f32(c) * u * u) * 0.5 * (1 - np.tanh((u - 1) / _f32(w)))
    lip_u = 1 + 3 * w + 0.05
    bowl += _f32(gm["fp_lip"] * lip_scale) * np.exp(-((u - _f32(lip_u)) / _f32(0.06)) ** 2)
    return bowl, u, lip_u


def _ejector(xg, yg, gm, R, aa):
    """Footprint (0..1) and striae of the ejector mark, 700 µm in from the rim."""
    ea = gm["ejector_angle"]
    re = R - 700.0
    du, dv = _rotate(xg - _f32(re * math.cos(ea)), yg - _f32(re * math.sin(ea)), ea)
    a, b = gm["ejector_size"]
    w = max(20.0, aa)
    box = _soft(_f32(a) - np.abs(du), w) * _soft(_f32(b) - np.abs(dv), w)
    striae = np.sin(_f32(2 * np.pi / 35.0) * dv + _f32(ea * 7))
    return box, striae
