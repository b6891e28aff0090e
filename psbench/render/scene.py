"""Synthetic photometric-stereo images with ground truth (thesis Sections 2.3, 5.2, 5.3).

:func:`render` shades a height-field surface under k lights with the Lambert
(Eq. 2.12), Phong (Eq. 2.13), Torrance–Sparrow (Eq. 2.14–2.15) or GGX microfacet
(:mod:`psbench.render._ggx`) model, puts in
self and cast shadows, adds Gaussian camera noise and optional quantisation,
and returns a :class:`Scene` holding the image stack and the per-image ground
truth (highlights, self shadows, cast shadows) that the quality factor needs.

Defaults follow Table 5.1: Torrance–Sparrow, rho_d = rho_s = 1, m = 2, light
power 1, orthographic camera v = (0, 0, 1), distant lights, no inverse-square
falloff, no perspective.

Conventions
-----------
Frame x right, y up (y = -row), camera at +z; pixel (r, c) sits at
x = c - (W-1)/2, y = (H-1)/2 - r, z = height (pixel units). Light directions
point from the surface towards the light. Everything is float32, computed light
by light into preallocated (k, H, W) stacks.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._shared.checks import PsbenchError, choice
from .._shared.deprecation import warn_renamed
from .._shared.memory import managed_memory
from ..lights import Layout, layout
from ._shading import (HIGHLIGHT_ANGLE, HIGHLIGHT_FRACTION, HIGHLIGHT_RULES, Shader, _nonneg,
                       _positive, highlight_plane, highlight_truth)
from ._shading import highlight_rule as _highlight_rule
from .shadowmap import point_shadow_map, shadow_map
from . import _departures

__all__ = ["render", "Scene", "MODELS", "SHADOWS", "HIGHLIGHT_RULES", "HIGHLIGHT_ANGLE",
           "HIGHLIGHT_FRACTION"]

#: reflection models
MODELS = ("lambert", "phong", "ts", "ggx")
#: accepted values of ``shadows``
SHADOWS = (True, False, "all", "self", "none")
#: quantisation bit depths accepted by ``quantize``
QUANTIZE_BITS = tuple(range(1, 17))


@dataclass(eq=False, repr=False)
class Scene:
    """A rendered image stack with ground truth.

    Attributes
    ----------
    images : (k, H, W) float32
        Rendered images (noise and quantisation applied); 0 outside the object mask.
    highlight : (k, H, W) bool
        Ground-truth highlight on lit object pixels, by ``highlight_rule`` (see
        :func:`render`): the normal within ``highlight_angle`` of the source-camera
        bisector (``"cone"``, default) or the specular term above
        ``highlight_fraction`` of the clean image's range (``"range"``).
    self_shadow : (k, H, W) bool
        s.n <= 0 on the object.
    cast_shadow : (k, H, W) bool
        Occluded by the height field and not self-shadowed, on the object.
    surface : object
        The rendered surface (``.height .object_mask .normals``).
    lights : Layout
        The lights (with ``positions`` for near lights).
    model : str
    noise : float
        Noise setting (fraction of each image's dynamic range).
    seed : int
    sigma : (k,) float32
        Standard deviation of the noise added to each image.
    dynamic_range : (k,) float32
        max - min of each clean image over the object mask.
    shadows : bool or str
    quantize : int or None
    highlight_rule : {"cone", "range"}
    highlight_angle : float or None
        Cone half-angle in degrees (``"cone"``), else None.
    highlight_fraction : float or None
        Fraction of the image range (``"range"``), else None.
    bounces : int
        Interreflection bounces rendered (0: none).
    """

    images: np.ndarray
    highlight: np.ndarray
    self_shadow: np.ndarray
    cast_shadow: np.ndarray
    surface: Any
    lights: Layout
    model: str
    noise: float
    seed: int
    sigma: np.ndarray
    dynamic_range: np.ndarray
    shadows: Any = True
    quantize: int | None = None
    highlight_fraction: float | None = None
    highlight_rule: str = "cone"
    highlight_angle: float | None = HIGHLIGHT_ANGLE
    _shader: Any = field(default=None, repr=False)
    _cache: dict = field(default_factory=dict, repr=False)
    bounces: int = 0

    @property
    def shadow(self) -> np.ndarray:
        """(k, H, W) bool: self or cast shadow."""
        return self.self_shadow | self.cast_shadow

    @property
    def object_mask(self) -> np.ndarray:
        """(H, W) bool object mask of the surface."""
        return np.asarray(_object_mask(self.surface, stacklevel=4), dtype=bool)

    @property
    def k(self) -> int:
        return int(self.images.shape[0])

    @property
    def shape(self) -> tuple:
        return tuple(self.images.shape[1:])

    def _parts(self):
        if "diffuse" not in self._cache:
            diff, spec = self._shader.components(self.self_shadow | self.cast_shadow)
            self._cache["diffuse"], self._cache["specular"] = diff, spec
        return self._cache["diffuse"], self._cache["specular"]

    def highlight_truth(self, *, highlight=None, highlight_angle=None,
                        highlight_fraction=None) -> np.ndarray:
        """(k, H, W) bool ground-truth highlight of this scene under another definition
        (the options of :func:`render`; the images do not depend on it): equal to
        ``render(..., highlight=..., ...).highlight`` of the same scene."""
        rule, angle, fraction = _highlight_rule(highlight, highlight_angle, highlight_fraction)
        cos_t = np.float32(np.cos(np.radians(angle))) if rule == "cone" else None
        return highlight_truth(self._shader, self.self_shadow | self.cast_shadow,
                               self.dynamic_range, cos_t=cos_t, fraction=fraction)

    @property
    def diffuse(self) -> np.ndarray:
        """(k, H, W) float32 clean Lambert part (light power, falloff and shadows
        applied, no noise), computed on first use."""
        return self._parts()[0]

    @property
    def specular(self) -> np.ndarray:
        """(k, H, W) float32 clean specular part (zero for ``lambert``), computed on
        first use."""
        return self._parts()[1]

    @property
    def clean(self) -> np.ndarray:
        """(k, H, W) float32 noiseless, unquantised images (diffuse + specular, plus the
        secondary light when ``bounces`` > 0)."""
        d, s = self._parts()
        out = d + s
        if "secondary" in self._cache:
            out += self._cache["secondary"]
        return out

    @property
    def secondary_fraction(self) -> np.ndarray:
        """(k, H, W) float32 ground truth: the fraction of each clean pixel's intensity
        that is secondary light (interreflections, ``render(..., bounces=1|2)``); 0 where
        the clean pixel is 0, and everywhere when ``bounces`` = 0."""
        if "secondary_fraction" not in self._cache:
            self._cache["secondary_fraction"] = np.zeros(self.images.shape, np.float32)
        return self._cache["secondary_fraction"]

    def __repr__(self) -> str:
        k, H, W = self.images.shape
        return (f"Scene(model={self.model!r}, lights={self.lights.name!r}, k={k}, "
                f"shape=({H}, {W}), noise={self.noise:g}, seed={self.seed})")


@managed_memory
def render(surface, lights, *, model="ts", shadows=True, noise=0.0, seed=0,
           rho_d=1.0, rho_s=1.0, m=2.0, quantize=None, highlight=None, highlight_angle=None,
           highlight_fraction=None, light_positions=None, falloff=False, perspective=None,
           phong_m=20.0, shadow_bias=0.05, bounces=0, bounce_samples=24, roughness=0.3,
           f0=0.04, albedo_texture=0.0, second_material=None, light_error=0.0,
           power_error=0.0, light_distance=None, ambient=0.0, saturation=None,
           gamma=1.0) -> Scene:
    """Render a photometric-stereo image stack with ground truth.

    Parameters
    ----------
    surface : object with ``.height (H, W)``, ``.object_mask (H, W) bool``, ``.normals (H, W, 3)``
        E.g. :func:`psbench.make_surface`; any object with these fields works.
        Heights are in pixel units. The whole height field casts shadows (also
        outside the mask); non-finite heights are treated as the lowest height.
    lights : Layout, (k, 3) array_like or str
        Distant lights (:func:`psbench.layout`: ``"45x8"``, ``"30x8+60x8"``, ...);
        ``power`` (mu) scales every term of image i. Directions below the horizon
        (z < 0) are refused.
    model : {"ts", "lambert", "phong", "ggx"}
        ``"lambert"``: I = mu rho_d (s.n) (Eq. 2.12).
        ``"phong"``: I = mu [rho_s max(r.v, 0)^phong_m + rho_d (s.n)],
        r = 2 (s.n) n - s (Eq. 2.13).
        ``"ts"`` (Torrance–Sparrow): I = mu [rho_s exp(-m^2 arccos(n_h.n)^2) + rho_d (s.n)],
        n_h = (v + s) / |v + s| (Eq. 2.14–2.15).
        ``"ggx"``: I = mu [rho_s pi f_s(s, v) (s.n) + rho_d (s.n)], f_s the GGX
        (Trowbridge–Reitz) microfacet BRDF F G1(s.n) G1(v.n) D(n_h.n) / (4 (s.n)(v.n))
        with D = alpha^2 / (pi ((n_h.n)^2 (alpha^2 - 1) + 1)^2), Smith
        G1(c) = 2c / (c + sqrt(alpha^2 + (1 - alpha^2) c^2)) and Schlick
        F = F0 + (1 - F0)(1 - v.n_h)^5; alpha = ``roughness``, F0 = ``f0``
        (:mod:`psbench.render._ggx`). A lobe no solver of psbench models.
        Both terms are 0 where s.n <= 0 (self shadow) and in cast shadow. Cast
        shadows come from :func:`psbench.render.shadowmap.shadow_map` on
        ``surface.height`` (``bias=shadow_bias``, 2x oversampled sweep).
    shadows : {True, "all", False, "self", "none"}
        True / ``"all"``: self and cast shadows. False / ``"self"``: no cast
        shadows; self-shadowed points (s.n <= 0) are still 0, because light
        cannot be negative, and are still reported in ``self_shadow`` (the two
        spellings are equivalent). ``"none"``: no shadows at all, the
        mathematical "no shadow" assumption of the optimal-lighting analyses
        (Section 2.4, Fig. 4.3/4.4 "Di" images): the model is evaluated
        unclamped, so I = mu rho_d (s.n) (+ specular) may be negative where
        s.n <= 0; ``self_shadow`` and ``cast_shadow`` are all False. Least
        squares is then exact up to noise; note the dynamic range (and so the
        noise sigma) includes the negative values. Not a physical camera image.
    noise : float, default 0
        Additive zero-mean Gaussian noise, sigma_i = noise * (max_i - min_i) of the
        clean image i over the object mask (0.05 = 5 %). Added on the object only;
        results are not clipped (unless ``quantize``).
    seed : int
        Seed of ``numpy.random.default_rng`` for the noise.
    rho_d, rho_s : float or (H, W) array_like
        Diffuse and specular albedo (>= 0).
    m : float or (H, W) array_like, default 2
        Torrance–Sparrow roughness/shininess (> 0; Table 5.1 uses 2).
    roughness, f0 : float or (H, W) array_like, default 0.3, 0.04
        GGX roughness alpha (> 0) and Fresnel reflectance at normal incidence (in [0, 1];
        0.04 is a common dielectric); ``model="ggx"`` only.
    phong_m : float or (H, W) array_like, default 20
        Phong exponent (> 0), separate from ``m`` because the Phong lobe needs a
        much larger exponent to be comparably narrow.
    quantize : int, optional
        Bit depth q in 1..16: after noise, images are clipped to [0, M] with M the
        stack maximum over the object and rounded to 2^q - 1 levels of M; the
        result stays float32 in the same scale (an ideal q-bit camera whose full
        scale is the brightest pixel).
    highlight : {"cone", "range"}, optional
        Definition of the ground-truth highlight (the positives of the highlight
        quality factor, Eq. 2.32; the images do not depend on it). The thesis does
        not define it. Both count lit, unshadowed object observations of a model
        with a specular term (never for ``"lambert"``):

        * ``"cone"`` (default): the reflection cone, angle(n, n_h) <
          ``highlight_angle`` with n_h the source-camera bisector (the geometry of
          the thesis's reflection mask, Eqs. 3.8 / 5.1); local and independent of
          the image range, the model and its lobe width.
        * ``"range"``: the specular term above ``highlight_fraction`` x (max - min)
          of the clean image over the object mask.

        None: ``"range"`` when ``highlight_fraction`` is given, else ``"cone"``.
        The default cone of 12 deg is the middle of the half-angles (11-13 deg)
        under which every statement of the thesis's Fig. 5.8 holds (4 lights at
        30/45/60 deg on sombrero1-3 and the semisphere, 512^2): every sombrero and
        sphere pixel keeps >= 2 diffuse observations and highlights never take a
        pixel's second one; the sombrero has the fewest highlighted or shadowed
        observations at 45 deg, the sphere at 30 deg. The ``"range"`` rule with
        fraction 0.1 (psbench's earlier default) flags 22-81 % of the lit
        observations and leaves 46 % of the sombrero's pixels at 45x4 with fewer
        than 2 diffuse observations.
    highlight_angle : float, default 12
        Cone half-angle in degrees, in (0, 90) (``highlight="cone"`` only).
    highlight_fraction : float, default 0.1
        Fraction of the clean image's range, >= 0 (``highlight="range"`` only).
    light_positions : (k, 3) array_like, optional
        Near point lights at these positions (pixel units, origin at the image
        centre on the height datum, z up; z > 0). The direction is then computed
        per pixel from the surface point to the light. Default: ``lights.positions``
        if the layout has them, else distant lights. The returned layout's
        directions are those from the image centre (height 0) to each light.
        Shading, self shadows and cast shadows (:func:`psbench.render.shadowmap.point_shadow_map`,
        a perspective shadow map around the light's foot point) are per pixel.
    falloff : bool, default False
        Near lights only: multiply by (d0 / |L - p|)^2, d0 = |L| (distance to the
        image centre at height 0), so that point gets power mu.
    perspective : float, optional
        Focal length f in pixels: the camera sits at (0, 0, f) and the view
        vector of each pixel points from the surface point to it (used by the
        specular term). The image grid itself stays orthographic (the
        simplification of Section 5.2.2.2: depth variation << distance).
        f must exceed the highest surface point. None: v = (0, 0, 1).
    shadow_bias : float, default 0.05
        ``bias`` passed to :func:`psbench.render.shadowmap.shadow_map` /
        :func:`~psbench.render.shadowmap.point_shadow_map` (pixel-height units; the
        rendered heights are exact, so it is small).
    bounces : {0, 1, 2}, default 0
        Interreflections: light reflected once (1) or twice (2) between surface
        points that see each other is added to the direct images (unchanged);
        ``Scene.secondary_fraction`` is its share of each clean pixel. Distant lights
        and the orthographic camera only. Model and equations:
        :mod:`psbench.render._interreflect`.
    bounce_samples : int, default 24
        Direction sampling density of the interreflections: azimuths of the
        quadrature (x ~0.64 as many elevation bins); cost grows as its square.
    albedo_texture, second_material, light_error, power_error, light_distance, ambient, saturation, gamma
        Departures from the solvers' model (defaults: none), defined in
        :mod:`psbench.render._departures`: ``albedo_texture`` c in [0, 1) multiplies rho_d by
        a smooth seeded texture in [1 - c, 1]; ``second_material`` (a mapping of
        ``rho_s``, ``m``, ``roughness``, ``f0``, ``phong_m``) on the right half of the
        image; ``light_error`` (degrees) and ``power_error`` (fraction) render each
        light rotated by that angle / with its power times 1 + U(-e, e) (seeded; the
        scene's ``lights`` are the rendered ones); ``light_distance`` (image sides) puts
        near point lights along the nominal directions; ``ambient`` adds that fraction
        of the largest image range; ``saturation`` clips at that fraction of the stack
        maximum; ``gamma`` applies the unlinearized response M (I / M)^(1/gamma).

    Returns
    -------
    Scene
        ``.images (k, H, W) float32``, ground truth ``.highlight .self_shadow
        .cast_shadow (k, H, W) bool``, ``.sigma (k,)``, lazily computed
        ``.diffuse .specular .clean``. Pixels outside ``surface.object_mask`` are 0.
    """
    model = choice(model, MODELS, "model")
    if not (isinstance(shadows, (bool, np.bool_)) or shadows in ("all", "self", "none")):
        raise PsbenchError(f"shadows={shadows!r} is not known; valid choices: "
                           "True, False, 'all', 'self', 'none'")
    cast = bool(shadows) if isinstance(shadows, (bool, np.bool_)) else shadows == "all"
    noise = _nonneg(noise, "noise")
    dep = _departures.check(albedo_texture=albedo_texture, second_material=second_material,
                            light_error=light_error, power_error=power_error,
                            light_distance=light_distance, ambient=ambient,
                            saturation=saturation, gamma=gamma)
    rule, h_angle, h_fraction = _highlight_rule(highlight, highlight_angle, highlight_fraction)
    shadow_bias = _nonneg(shadow_bias, "shadow_bias")
    if quantize is not None:
        if isinstance(quantize, (bool, np.bool_)) or not isinstance(quantize, (int, np.integer)) \
                or int(quantize) not in QUANTIZE_BITS:
            raise PsbenchError(f"quantize={quantize!r}: expected None or a bit depth, an integer in 1..16")
        quantize = int(quantize)
    try:
        seed = int(seed)
    except (TypeError, ValueError):
        raise PsbenchError(f"seed must be an integer, got {seed!r}") from None

    height, object_mask, normals = _surface(surface)
    H, W = object_mask.shape
    rho_d = _albedo(rho_d, "rho_d", (H, W))
    rho_s = _albedo(rho_s, "rho_s", (H, W))
    m = _lobe(m, "m", (H, W))
    phong_m = _lobe(phong_m, "phong_m", (H, W))
    roughness = _lobe(roughness, "roughness", (H, W))
    f0 = _albedo(f0, "f0", (H, W))
    if float(np.max(f0)) > 1:
        raise PsbenchError(f"f0 must be in [0, 1], got a maximum of {float(np.max(f0)):g}")
    lay = _lights(lights)
    k = lay.k
    if dep["light_distance"] is not None and (light_positions is not None
                                              or lay.positions is not None):
        raise PsbenchError("light_distance places near lights itself; do not also pass "
                           "light_positions or a layout with positions")
    if dep["light_error"] or dep["power_error"]:
        d, pw = _departures.perturb_lights(lay.directions, lay.power, seed=seed,
                                           light_error=dep["light_error"],
                                           power_error=dep["power_error"])
        lay = Layout(d, pw, lay.ring, np.degrees(np.arccos(np.clip(d[:, 2], -1, 1))),
                     np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360.0, lay.name, lay.positions)
    if dep["light_distance"] is not None:
        light_positions = _departures.near_positions(lay.directions, width=W,
                                                     light_distance=dep["light_distance"])
    if dep["albedo_texture"]:
        rho_d = rho_d * _departures.albedo_texture((H, W), contrast=dep["albedo_texture"],
                                                   seed=seed)
    if dep["second_material"]:
        base = dict(rho_s=rho_s, m=m, roughness=roughness, f0=f0, phong_m=phong_m)
        got = _departures.second_material((H, W), dep["second_material"], base)
        rho_s, m, roughness = (got.get(n, base[n]) for n in ("rho_s", "m", "roughness"))
        f0, phong_m = got.get("f0", f0), got.get("phong_m", phong_m)
    camera = dict(ambient=dep["ambient"], saturation=dep["saturation"], gamma=dep["gamma"])

    pos = light_positions if light_positions is not None else lay.positions
    if pos is not None:
        pos = np.asarray(pos, dtype=np.float64)
        name = "light_positions" if light_positions is not None else "lights.positions"
        if pos.shape != (k, 3):
            raise PsbenchError(f"{name} must have shape ({k}, 3) to match {k} lights, got {pos.shape}")
        if not np.isfinite(pos).all():
            raise PsbenchError(f"{name} holds NaN/inf values")
        if (pos[:, 2] <= 0).any():
            raise PsbenchError(f"{name}: light(s) {np.flatnonzero(pos[:, 2] <= 0).tolist()} "
                               "are not above the height datum (z must be > 0)")
        d = pos / np.linalg.norm(pos, axis=1)[:, None]
        zen = np.degrees(np.arccos(np.clip(d[:, 2], -1, 1)))
        pol = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360.0
        lay = Layout(d, lay.power, lay.ring, zen, pol, lay.name, pos)
    if falloff and pos is None:
        raise PsbenchError("falloff=True needs near lights: pass light_positions (k, 3)")
    if perspective is not None:
        f = _positive(perspective, "perspective")
        top = float(np.max(height, where=object_mask, initial=0.0))
        if f <= top:
            raise PsbenchError(f"perspective={f:g}: the camera (0, 0, f) must be above the surface "
                               f"(highest point {top:g})")
        perspective = f
    if isinstance(bounces, (bool, np.bool_)) or not isinstance(bounces, (int, np.integer)) \
            or bounces not in (0, 1, 2):
        raise PsbenchError(f"bounces must be 0, 1 or 2, got {bounces!r}")
    if bounces:  # interreflections: the noiseless direct scene, then the secondary light
        from ._interreflect import add_bounces, check_bounces
        check_bounces(bounce_samples, pos, perspective, shadows)
        if model == "ggx" or np.ndim(m) or np.ndim(phong_m):
            raise PsbenchError("bounces > 0 needs model lambert, phong or ts with a scalar m "
                               "and phong_m (no GGX, no second_material lobe)")
        scene = render(surface, lay, model=model, shadows=shadows, noise=0.0, seed=seed,
                       rho_d=rho_d, rho_s=rho_s, m=m, phong_m=phong_m,
                       highlight=highlight, highlight_angle=highlight_angle,
                       highlight_fraction=highlight_fraction, shadow_bias=shadow_bias)
        scene = add_bounces(scene, height, object_mask, normals, bounces=int(bounces),
                            samples=int(bounce_samples), noise=noise, seed=seed, model=model,
                            rho_d=rho_d, rho_s=rho_s, m=m, phong_m=phong_m)
        _departures.camera(scene.images, object_mask, scene.dynamic_range, **camera)
        if quantize is not None:
            _quantize(scene.images, object_mask, quantize)
            scene.quantize = quantize
        return scene

    shader = Shader(height, object_mask, normals, lay, model, rho_d, rho_s, m, phong_m,
                    pos, bool(falloff), perspective,
                    clamp=not (isinstance(shadows, str) and shadows == "none"),
                    half_cos=rule == "cone" and model != "lambert", roughness=roughness, f0=f0)
    cos_t = np.float32(np.cos(np.radians(h_angle))) if rule == "cone" else None
    occluded = None
    if cast:
        occluded = (shadow_map(height, lay.directions, bias=shadow_bias) if pos is None else
                    point_shadow_map(height, pos, bias=shadow_bias))

    images = np.empty((k, H, W), dtype=np.float32)
    highlight = np.zeros((k, H, W), dtype=bool)
    self_sh = np.zeros((k, H, W), dtype=bool)
    cast_sh = np.zeros((k, H, W), dtype=bool)
    drange = np.zeros(k, dtype=np.float32)
    sigma = np.zeros(k, dtype=np.float32)
    rng = np.random.default_rng(seed)
    full = bool(object_mask.all())
    outside = None if full else ~object_mask
    dark = np.empty((H, W), dtype=bool)
    keep = np.empty((H, W), dtype=bool)
    z = None  # noise buffer
    for i in range(k):
        diff, spec, lit = shader.light(i)
        np.logical_not(lit, out=dark)  # dark: self or cast shadow, or off the object
        np.copyto(self_sh[i], dark)
        if outside is not None:
            self_sh[i] &= object_mask
            dark |= outside
        if occluded is not None:
            np.logical_and(occluded[i], lit, out=cast_sh[i])
            if outside is not None:
                cast_sh[i] &= object_mask
            dark |= cast_sh[i]
        img = images[i]
        if spec is None:
            np.copyto(img, diff)
        else:
            np.add(diff, spec, out=img)
        np.logical_not(dark, out=keep)
        np.multiply(img, keep, out=img)  # much faster than img[dark] = 0 or copyto(where)
        if full:
            hi, lo = float(img.max()), float(img.min())
        else:
            hi = float(np.max(img, where=object_mask, initial=-np.inf))
            lo = float(np.min(img, where=object_mask, initial=np.inf))
        drange[i] = hi - lo if np.isfinite(hi) else 0.0
        if spec is not None:
            highlight_plane(highlight[i], spec, shader.cos_h, keep, cos_t=cos_t,
                            threshold=None if cos_t is not None else h_fraction * drange[i])
        if noise > 0:
            sigma[i] = np.float32(noise * drange[i])
            if z is None:
                z = np.empty((H, W), dtype=np.float32)
            rng.standard_normal(dtype=np.float32, out=z)
            z *= sigma[i]
            if outside is not None:
                z *= object_mask
            img += z
    _departures.camera(images, object_mask, drange, **camera)
    if quantize is not None:
        _quantize(images, object_mask, quantize)
    return Scene(images, highlight, self_sh, cast_sh, surface, lay, model, float(noise), seed,
                 sigma, drange, shadows, quantize, h_fraction, rule, h_angle, shader)


def _quantize(images, object_mask, bits):
    """Round the (k, H, W) ``images`` in place to ``bits``-bit levels of their maximum
    over the (H, W) bool ``object_mask``."""
    top = float(np.max(images, where=object_mask[None], initial=0.0))
    if top <= 0:
        images[...] = 0.0
        return
    levels = float(2 ** bits - 1)
    scale = np.float32(levels / top)
    for img in images:  # in place, light by light
        np.clip(img, 0.0, top, out=img)
        img *= scale
        np.rint(img, out=img)
        img *= np.float32(top / levels)




def _albedo(value, name, shape):
    a = np.asarray(value, dtype=np.float32)
    if a.ndim == 0:
        v = float(a)
        if not np.isfinite(v) or v < 0:
            raise PsbenchError(f"{name} must be >= 0, got {value!r}")
        return np.float32(v)
    if a.shape != shape:
        raise PsbenchError(f"{name} must be a number or have shape {shape}, got {a.shape}")
    if not np.isfinite(a).all() or (a < 0).any():
        raise PsbenchError(f"{name} must be finite and >= 0 everywhere")
    return a


def _lobe(value, name, shape):
    """A lobe parameter: a number > 0 or an (H, W) array of them."""
    a = np.asarray(value, dtype=np.float32) if not isinstance(value, (bool, np.bool_)) \
        else np.float32(np.nan)
    if a.ndim == 0:
        return np.float32(_positive(value, name))
    if a.shape != shape:
        raise PsbenchError(f"{name} must be a number or have shape {shape}, got {a.shape}")
    if not np.isfinite(a).all() or (a <= 0).any():
        raise PsbenchError(f"{name} must be finite and > 0 everywhere")
    return a


def _object_mask(surface, *, stacklevel=3):
    """``surface.object_mask``; a surface-like object with only the old ``.mask`` still
    works, with a DeprecationWarning."""
    if hasattr(surface, "object_mask"):
        return surface.object_mask
    warn_renamed(f"a surface ({type(surface).__name__}) with .mask instead of .object_mask",
                 ".object_mask", stacklevel=stacklevel)
    return surface.mask


def _surface(surface):
    """Checked (height (H, W) float32, object_mask (H, W) bool, normals (H, W, 3) float32)
    of a surface-like object; non-finite values off the object replaced."""
    missing = [f for f in ("height", "normals") if not hasattr(surface, f)]
    if not (hasattr(surface, "object_mask") or hasattr(surface, "mask")):
        missing.insert(1, "object_mask")
    if missing:
        raise PsbenchError(
            f"surface must have fields height, object_mask and normals (e.g. "
            f"psbench.make_surface(...)); {type(surface).__name__} lacks {', '.join(missing)}")
    height = np.asarray(surface.height)
    if height.ndim != 2 or height.dtype == bool or not np.issubdtype(height.dtype, np.number):
        raise PsbenchError(f"surface.height must be a numeric (H, W) array, got shape {height.shape}")
    H, W = height.shape
    object_mask = np.asarray(_object_mask(surface, stacklevel=5))
    if object_mask.shape != (H, W):
        raise PsbenchError(f"surface.object_mask must have shape {(H, W)}, "
                           f"got {object_mask.shape}")
    object_mask = object_mask.astype(bool, copy=False)
    normals = np.asarray(surface.normals, dtype=np.float32)
    if normals.shape != (H, W, 3):
        raise PsbenchError(f"surface.normals must have shape {(H, W, 3)}, got {normals.shape}")
    height = height.astype(np.float32, copy=False)
    fin = np.isfinite(height)
    if not fin[object_mask].all():
        raise PsbenchError("surface.height holds NaN/inf inside surface.object_mask")
    if not fin.all():
        height = np.where(fin, height, np.float32(height[fin].min() if fin.any() else 0.0))
    nfin = np.isfinite(normals).all(axis=2)
    if not nfin[object_mask].all():
        raise PsbenchError("surface.normals holds NaN/inf inside surface.object_mask")
    if not nfin.all():
        normals = np.where(nfin[..., None], normals, np.float32([0, 0, 1]))
    return height, object_mask, normals


def _lights(lights):
    if isinstance(lights, Layout):
        lay = lights
    else:
        arr = None if isinstance(lights, str) else np.asarray(lights, dtype=np.float64)
        if arr is not None and arr.ndim == 2 and arr.shape[1] == 3 and arr.shape[0] < 3:
            from .shadowmap import light_directions
            d = light_directions(arr, "lights")  # fewer than 3 lights: render anyway
            zen = np.degrees(np.arccos(np.clip(d[:, 2], -1, 1)))
            pol = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360.0
            lay = Layout(d, np.ones(len(d)), np.zeros(len(d), dtype=int), zen, pol, "custom")
        else:
            lay = layout(lights)
    below = np.flatnonzero(np.asarray(lay.directions)[:, 2] < -1e-12)
    if below.size:
        raise PsbenchError(f"lights: direction(s) {below.tolist()} point below the horizon (z < 0)")
    return lay
