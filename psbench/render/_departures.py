"""Departures from the solvers' model, as options of :func:`psbench.render.render`.

The solvers assume distant lights of known direction and power, a linear camera that
does not clip, one material and (Lambertian robust solvers) a Lambertian surface apart
from outliers. Each option below breaks one of these assumptions by a stated amount, so
that a stress grid can ask what each departure costs:

``albedo_texture`` (c in [0, 1))
    rho_d is multiplied by 1 - c t(x, y), t in [0, 1] a smooth texture: the sum of six
    plane waves with seeded directions, phases and periods of 1/8 to 1/3 of the image
    side, rescaled to [0, 1]. Seeded by ``seed`` (a stream apart from the noise).
``second_material`` (mapping)
    A second material on the right half of the image (columns >= W / 2): the given
    values of ``rho_s``, ``m`` (Torrance-Sparrow lobe), ``roughness`` / ``f0`` (GGX),
    ``phong_m`` replace the first material's there.
``light_error`` (degrees, in [0, 30])
    Each light is rendered rotated by exactly this angle away from its nominal direction,
    towards a seeded random azimuth around it; the scene's ``lights`` are the rendered
    ones, the solver is given the nominal ones.
``power_error`` (fraction, in [0, 1))
    Each light's power is multiplied by 1 + u, u uniform in [-e, e] (seeded).
``light_distance`` (image sides, > 0)
    Near point lights at ``light_distance`` x W along the nominal directions (from the
    image centre at height 0), rendered per pixel (``light_positions``); a solver given
    the nominal directions treats them as distant. Add ``falloff=True`` for the
    inverse-square law.
``ambient`` (fraction, >= 0)
    A constant offset of ``ambient`` x the largest clean image range added to every
    object pixel of every image (stray light, an unsubtracted dark level).
``saturation`` (fraction, in (0, 1])
    Images clipped at ``saturation`` x the stack maximum over the object (after noise
    and ambient): a camera whose highlights saturate.
``gamma`` (> 0)
    A camera response that was not linearized: I -> M (clip(I, 0, M) / M)^(1/gamma), M
    the full scale (the saturation level, else the stack maximum); 2.2 is sRGB-like.

Order of the camera: shading (perturbed lights, textures) -> noise -> ambient ->
saturation -> response -> ``quantize``. Everything is computed light by light in place
on the (k, H, W) stack.
"""
from __future__ import annotations

import numpy as np

from .._shared.checks import PsbenchError

__all__ = ["SECOND_MATERIAL_KEYS", "check", "perturb_lights", "near_positions",
           "albedo_texture", "second_material", "camera"]

#: the render options a second material may override
SECOND_MATERIAL_KEYS = ("rho_s", "m", "roughness", "f0", "phong_m")
#: seed streams (apart from the noise stream of ``default_rng(seed)``)
_LIGHT_STREAM, _TEXTURE_STREAM = 7, 11


def _number(value, name, lo, hi, *, lo_open=False, hi_open=False, what=""):
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if isinstance(value, (bool, np.bool_)) or not np.isfinite(v) or \
            (v <= lo if lo_open else v < lo) or (v >= hi if hi_open else v > hi):
        raise PsbenchError(f"{name} must be a number in {'(' if lo_open else '['}{lo:g}, "
                           f"{'inf' if hi == np.inf else f'{hi:g}'}{')' if hi_open else ']'}"
                           f"{what}, got {value!r}")
    return v


def check(*, albedo_texture, second_material, light_error, power_error, light_distance,
          ambient, saturation, gamma):
    """Validated departure options (one-line errors naming the option)."""
    out = dict(
        albedo_texture=_number(albedo_texture, "albedo_texture", 0, 1, hi_open=True),
        light_error=_number(light_error, "light_error", 0, 30, what=" degrees"),
        power_error=_number(power_error, "power_error", 0, 1, hi_open=True),
        ambient=_number(ambient, "ambient", 0, np.inf, hi_open=True),
        gamma=_number(gamma, "gamma", 0, np.inf, lo_open=True, hi_open=True),
        light_distance=None if light_distance is None else _number(
            light_distance, "light_distance", 0, np.inf, lo_open=True, hi_open=True,
            what=" image sides"),
        saturation=None if saturation is None else _number(
            saturation, "saturation", 0, 1, lo_open=True),
        second_material=None)
    if second_material is not None:
        if not isinstance(second_material, dict) or not second_material:
            raise PsbenchError(f"second_material must be a non-empty mapping of "
                               f"{', '.join(SECOND_MATERIAL_KEYS)}, got {second_material!r}")
        bad = sorted(set(map(str, second_material)) - set(SECOND_MATERIAL_KEYS))
        if bad:
            raise PsbenchError(f"second_material: unknown key(s) {bad}; valid: "
                               f"{', '.join(SECOND_MATERIAL_KEYS)}")
        sm = {}
        for k, v in second_material.items():
            sm[k] = _number(v, f"second_material.{k}", 0, 1 if k == "f0" else np.inf,
                            lo_open=k in ("m", "roughness", "phong_m"),
                            hi_open=k != "f0")
        out["second_material"] = sm
    return out


def _rng(seed, stream):
    return np.random.default_rng([int(seed) & 0xFFFFFFFF, stream])


def perturb_lights(directions, power, *, light_error, power_error, seed):
    """Rendered light directions (k, 3) and powers (k,): each direction rotated by
    ``light_error`` degrees towards a random azimuth about it, each power times 1 + u,
    u ~ U(-power_error, power_error)."""
    d = np.array(directions, dtype=np.float64)
    p = np.array(power, dtype=np.float64)
    rng = _rng(seed, _LIGHT_STREAM)
    k = len(d)
    phi = rng.uniform(0, 2 * np.pi, k)       # drawn even when unused: streams stay fixed
    u = rng.uniform(-1, 1, k)
    if light_error > 0:
        # an orthonormal pair perpendicular to each direction
        ref = np.where(np.abs(d[:, 2:3]) < 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
        a = np.cross(d, ref)
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        b = np.cross(d, a)
        t = np.radians(light_error)
        off = np.cos(phi)[:, None] * a + np.sin(phi)[:, None] * b
        d = np.cos(t) * d + np.sin(t) * off
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        below = np.flatnonzero(d[:, 2] < 0)
        if below.size:
            raise PsbenchError(f"light_error={light_error:g} puts light(s) {below.tolist()} "
                               "below the horizon; use a smaller error or higher lights")
    if power_error > 0:
        p = p * (1 + power_error * u)
    return d, p


def near_positions(directions, *, light_distance, width):
    """(k, 3) positions ``light_distance`` x ``width`` along each direction."""
    return np.asarray(directions, dtype=np.float64) * (float(light_distance) * float(width))


def albedo_texture(shape, *, contrast, seed):
    """(H, W) float32 factor 1 - contrast t(x, y) with t in [0, 1] smooth (see module)."""
    H, W = shape
    rng = _rng(seed, _TEXTURE_STREAM)
    n = 6
    ang = rng.uniform(0, np.pi, n)
    period = rng.uniform(1 / 8, 1 / 3, n) * max(H, W)
    phase = rng.uniform(0, 2 * np.pi, n)
    y = np.arange(H, dtype=np.float32)[:, None]
    x = np.arange(W, dtype=np.float32)[None, :]
    t = np.zeros((H, W), np.float32)
    for j in range(n):   # six waves, each one (H, W) pass
        w = np.float32(2 * np.pi / period[j])
        t += np.cos(x * np.float32(np.cos(ang[j]) * w) + y * np.float32(np.sin(ang[j]) * w)
                    + np.float32(phase[j]))
    lo, hi = float(t.min()), float(t.max())
    t -= np.float32(lo)
    t *= np.float32(contrast / (hi - lo) if hi > lo else 0.0)
    np.subtract(np.float32(1), t, out=t)
    return t


def second_material(shape, values, base):
    """The material options with ``values`` on the right half (columns >= W / 2).

    ``base`` maps each option of ``values`` to the first material's value (scalar or
    (H, W)); returns ``{option: (H, W) float32}``.
    """
    H, W = shape
    right = np.zeros((H, W), bool)
    right[:, W // 2:] = True
    return {k: np.where(right, np.float32(v), np.broadcast_to(
        np.asarray(base[k], np.float32), (H, W))).astype(np.float32) for k, v in values.items()}


def camera(images, object_mask, drange, *, ambient, saturation, gamma):
    """Apply ambient offset, saturation and response to ``images`` (k, H, W) in place.

    ``drange`` (k,) are the clean images' ranges (the ambient's unit). Pixels off the
    object stay 0.
    """
    if ambient == 0 and saturation is None and gamma == 1:
        return images
    object_mask = np.asarray(object_mask, bool)
    full = bool(object_mask.all())
    if ambient > 0:
        off = np.float32(ambient * float(np.max(drange, initial=0.0)))
        for img in images:
            img += off if full else off * object_mask
    top = float(np.max(images, where=object_mask[None], initial=0.0))
    scale = top if saturation is None else saturation * top
    if top <= 0:
        return images
    for img in images:  # light by light: no (k, H, W) temporaries
        if saturation is not None:
            np.minimum(img, np.float32(scale), out=img)
        if gamma != 1:
            np.clip(img, 0, np.float32(scale), out=img)
            img *= np.float32(1 / scale)
            np.power(img, np.float32(1 / gamma), out=img)
            img *= np.float32(scale)
        if not full:
            img *= object_mask
    return images
