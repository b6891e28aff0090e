"""Metal finishes and the Chapter 7 acquisition (BALISTIKA rig, thesis Section 7).

The thesis acquires the case head under 16 LEDs on two rings (zenith 31° and 62°, eight
each), 2048 x 2048 pixels, 8-bit, 4.9 µm per pixel, with one common exposure "selected
considering the mean value of all intensity values to be around 75" (of 255). Highlights
appear mostly under the 31° ring, highlights and shadows on the firing-pin walls under
the 62° ring.

:data:`FINISH_PRESETS` holds the Torrance–Sparrow parameters of :func:`psbench.render`
for the two finishes; :func:`acquire` renders a :class:`~psbench.forensic.Cartridge`
(or any surface) with its finish and per-pixel albedo, sets the exposure, adds camera
read noise, clips at full scale and quantizes to ``bits``.

The finishes are plausible, not measured: brass is a warm, moderately rough metal (a
broad lobe, TS ``m`` = 4: the lobe falls to 1/e at 14° from the mirror direction, so the
flat head face already glints under the 31° ring, whose half vector is 15.5° off the
view), nickel plating is brighter, more specular and smoother (``m`` = 6, 9.5°).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._shared.checks import PsbenchError, choice
from ..lights import layout
from ..render.scene import render

__all__ = ["Finish", "FINISH_PRESETS", "ACQUISITION", "Acquisition", "acquire"]


@dataclass(frozen=True)
class Finish:
    """Torrance–Sparrow appearance of a metal finish (:func:`psbench.render` model "ts").

    Attributes
    ----------
    name : str
    rho_d : float
        Diffuse albedo (scaled per pixel by the surface's ``albedo`` map, if any).
    rho_s : float
        Specular albedo.
    m : float
        Lobe width parameter: specular term ``rho_s exp(-m² a²)``, a the angle between
        the normal and the half vector (radians); larger is narrower.
    """

    name: str
    rho_d: float
    rho_s: float
    m: float


#: finish name -> Finish
FINISH_PRESETS = {
    "brass": Finish("brass", rho_d=0.35, rho_s=0.6, m=4.0),
    "nickel": Finish("nickel", rho_d=0.45, rho_s=0.9, m=6.0),
}

#: the Chapter 7 acquisition: lights, bit depth, target mean level (of 2^bits - 1)
ACQUISITION = {"lights": "31x8+62x8", "bits": 8, "mean_level": 75.0, "read_noise": 1.0}


@dataclass(eq=False)
class Acquisition:
    """An acquired image stack with the ground truth of its rendering.

    Attributes
    ----------
    images : (k, H, W) uint8 (uint16 for bits > 8)
        The quantized camera images (``psbench.solve`` divides unsigned images by
        their dtype's maximum).
    lights : Layout
    gain : float
        Exposure: camera counts per unit of rendered radiance.
    saturated : float
        Fraction of object observations clipped at full scale.
    highlight, shadow : (k, H, W) bool
        Ground truth of the render (specular term above 10 % of the image range; self
        or cast shadow), on the object.
    finish : Finish
    bits : int
    """

    images: np.ndarray
    lights: object
    gain: float
    saturated: float
    highlight: np.ndarray
    shadow: np.ndarray
    finish: Finish
    bits: int

    @property
    def mean_level(self):
        """Mean of all intensity values, in counts."""
        return float(self.images.mean(dtype=np.float64))


def acquire(surface, *, finish=None, lights=ACQUISITION["lights"], bits=ACQUISITION["bits"],
            mean_level=ACQUISITION["mean_level"], read_noise=ACQUISITION["read_noise"],
            shadows=True, seed=0):
    """Render and expose a surface as the Chapter 7 rig would.

    Parameters
    ----------
    surface : Cartridge or Surface
        Heights in pixel units; a ``Cartridge`` brings its ``finish`` and ``albedo``.
    finish : str or Finish, optional
        ``"brass"``, ``"nickel"`` or a :class:`Finish`; default the surface's own
        (``surface.finish``), else brass.
    lights : str, Layout or (k, 3) array_like, default "31x8+62x8"
    bits : int, default 8
        Bit depth, 1..16.
    mean_level : float, default 75
        The exposure is set so that the mean of all intensity values (every pixel of
        every image, before noise and clipping) is this many counts. Highlights brighter
        than full scale saturate.
    read_noise : float, default 1
        Gaussian read noise, standard deviation in counts (seeded).
    shadows : bool, default True
        Cast shadows (self shadows always).
    seed : int, default 0

    Returns
    -------
    Acquisition
    """
    if isinstance(bits, (bool, np.bool_)) or not isinstance(bits, (int, np.integer)) \
            or not 1 <= bits <= 16:
        raise PsbenchError(f"bits must be an integer in 1..16, got {bits!r}")
    full = float(2 ** int(bits) - 1)
    try:
        mean_level = float(mean_level)
        read_noise = float(read_noise)
    except (TypeError, ValueError):
        raise PsbenchError("mean_level and read_noise must be numbers") from None
    if not (0 < mean_level < full) or not math.isfinite(mean_level):
        raise PsbenchError(f"mean_level must be in (0, {full:g}) counts, got {mean_level!r}")
    if not (read_noise >= 0) or not math.isfinite(read_noise):
        raise PsbenchError(f"read_noise must be a finite number >= 0 counts, got {read_noise!r}")
    fin = _finish(finish if finish is not None else getattr(surface, "finish", "brass"))
    lay = layout(lights) if isinstance(lights, str) else lights
    albedo = getattr(surface, "albedo", None)
    rho_d = fin.rho_d if albedo is None else np.float32(fin.rho_d) * np.asarray(albedo, np.float32)
    sc = render(surface, lay, model="ts", rho_d=rho_d, rho_s=fin.rho_s, m=fin.m,
                shadows=bool(shadows), noise=0.0)
    images = sc.images
    gain = mean_level / max(float(images.mean(dtype=np.float64)), 1e-12)
    object_mask = np.asarray(surface.object_mask, bool)
    rng = np.random.default_rng(seed)
    out = np.empty(images.shape, np.uint8 if bits <= 8 else np.uint16)
    noise = np.empty(images.shape[1:], np.float32)
    clipped = 0
    for i, img in enumerate(images):           # in place, image by image: memory
        img *= np.float32(gain)
        if read_noise > 0:
            rng.standard_normal(dtype=np.float32, out=noise)
            noise *= np.float32(read_noise)
            img += noise
        clipped += int(np.count_nonzero((img >= full) & object_mask))
        np.clip(img, 0.0, full, out=img)
        np.rint(img, out=img)
        out[i] = img
    saturated = clipped / max(int(object_mask.sum()) * len(images), 1)
    highlight, shadow = sc.highlight, sc.self_shadow | sc.cast_shadow
    lay_out = sc.lights
    del sc, images
    return Acquisition(out, lay_out, gain, saturated, highlight, shadow, fin, int(bits))


def _finish(finish):
    if isinstance(finish, Finish):
        return finish
    return FINISH_PRESETS[choice(finish, tuple(FINISH_PRESETS), "finish")]
