"""Interreflections on a height field: light that bounces once (or twice) between
surface points that see each other.

Model
-----
Images are in psbench's units, ``I = pi L`` (L radiance), so a distant light of
power mu from direction s gives ``I = mu [rho_d (s.n) + rho_s S(n, s, v)]`` (Eq.
2.12-2.15; S is the Torrance-Sparrow lobe ``exp(-m^2 arccos(n.h)^2)`` or the Phong
lobe ``max(r.v, 0)^phong_m``, both zero where s.n <= 0). Secondary light treats
every visible surface point q as a small light: the radiance arriving from
direction w, ``L(w) = R_q(-w) / pi``, acts like a light of power ``L dw``, so

    I_sec(p) = int_{w.n_p > 0} R_q(w)(-w) / pi [rho_d(p) (w.n_p) + rho_s(p) S(n_p, w, v)] dw

where q(w) is the first point of the height field hit by the ray from p along w
and ``R_q(u) = mu [rho_d(q) (s.n_q) + rho_s(q) S(n_q, s, u)]`` (lit, s.n_q > 0,
not cast-shadowed; u the direction from q towards p) is what q sends towards p:
the direct image a camera at p would see. For Lambert surfaces this is the exact
radiosity one-bounce term ``I_sec(p) = rho(p) int B(q) cos_p cos_q / (pi r^2) dA_q``
with B = I_direct. A second bounce repeats the gather with the *diffuse* part of
the secondary light as emitter (``rho_d(q) int ... (w.n_q) dw``); the view-dependent
re-emission of secondary light by the specular lobe is left out (it would need the
whole incoming field per outgoing direction). Rays that leave the frame, or hit the
back of a surface, bring nothing (a black world around the height field).

Algorithm
---------
The integral is a quadrature over global directions: ``samples`` azimuths times
``round(2 samples / pi)`` (even) elevation bins of equal solid angle (uniform in
sin(elevation)) on the whole sphere, each of weight ``dw / pi = 4 / (n_az n_el)``;
the sample's place inside its elevation bin moves from one azimuth to the next (a
lattice, :func:`directions`). For one azimuth the height field is resampled on a
sheared grid whose columns are the rays' ground tracks (marching along the image
axis closest to the azimuth, one whole pixel per step, linear across rays -- as
:mod:`psbench.render.shadowmap`), so every ray of the azimuth is a column. For one
elevation with rise T per step the first hit of the ray from origin rho is the first
rho' > rho with ``g(rho') > g(rho) + bias``, ``g = h - T rho``, refined to the exact
crossing between rho' - 1 and rho' (the profile is piecewise linear along a
column), where the emission is interpolated. The compiled kernel
(:mod:`psbench._interreflect_kernel`, numba) finds the hits with one far-to-near
stack sweep per column and fuses the loop over lights; without numba the numpy
fallback (:mod:`psbench._interreflect_numpy`) uses binary lifting on a sparse table
of running maxima. Directions that cannot hit anything (steeper than the steepest
slope) or reach no receiver (below every tangent plane) are skipped. Origins and
emission on the working grid take their values from object pixels only (a sample
between an object and a background pixel is the object's). Results are mapped back
to the pixels by the exact inverse of the linear resampling.

Accuracy and limits
-------------------
Against the closed form of a Lambertian spherical cap and a brute-force patch sum
(:mod:`psbench._interreflect_ref`; ``benchmarks/bench_interreflect.py``): the
direction quadrature scatters pixels by about -5 % .. +4 % (5th-95th percentile) at
24 azimuths and -2 % .. +1 % at 48; the mean is low by O(1 / size) because the
bilinear height field cuts creases (a cup's rim, a groove's apex) about 0.4 px low:
-2.5 % at 64^2, -1.3 % at 128^2, -0.6 % at 256^2, -0.3 % at 512^2 on the cup; a
groove's apex column itself gets ~45 % too little (its 1-px neighbourhood is not
resolved).
Memory: per light, the padded emission, the accumulators and (TS/Phong) the lit
maps, about 4 x 4 bytes x H x W (1 GB at 2048^2 x 16).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._shared.checks import PsbenchError
from ._shading import lobe as _lobe

__all__ = ["secondary", "add_bounces", "Specular", "directions", "DEFAULT_SAMPLES", "MODELS"]

#: azimuths of the default direction set (24 x 16 bins on the sphere)
DEFAULT_SAMPLES = 24
MODELS = ("lambert", "ts", "phong")
#: working-grid elements per chunk (bounds the sparse table at ~12 x 2 MB)
_CHUNK = 1 << 19
_NOTHING = np.float32(-3e38)


@dataclass(frozen=True)
class Specular:
    """The specular part of the reflectance and what it needs of the lights.

    Attributes
    ----------
    model : {"ts", "phong"}
    rho_s : float or (H, W) float32
    m, phong_m : float
        Torrance-Sparrow roughness and Phong exponent.
    directions : (k, 3) float
        Unit light directions (distant lights).
    power : (k,) float
    lit : (k, H, W) bool
        Directly lit (s.n > 0 and not cast-shadowed), inside the object.
    """

    model: str
    rho_s: object
    m: float
    phong_m: float
    directions: np.ndarray
    power: np.ndarray
    lit: np.ndarray


def directions(samples):
    """(azimuths (n_az,), sin of elevations (n_az, n_el), quadrature weight dw / pi).

    ``samples`` azimuths, ``n_el = round(2 samples / pi)`` rounded up to even, so a
    bin is about square at the horizon; every bin has solid angle 4 pi / (n_az n_el).
    Within its sin(elevation) bin the sample of azimuth a sits at the fraction
    ``frac(0.5 + a g)`` (g the golden ratio): the offsets differ from one azimuth to
    the next (a lattice rather than a product grid), which halves the error on
    integrands with edges (shadow and rim boundaries) at the same cost.
    """
    n_az = int(samples)
    n_el = max(2, int(round(2.0 * n_az / math.pi)))
    n_el += n_el % 2
    az = 2.0 * math.pi * (np.arange(n_az) + 0.5) / n_az
    off = (0.5 + np.arange(n_az) * 0.6180339887498949) % 1.0
    sin_el = -1.0 + 2.0 * (np.arange(n_el)[None, :] + off[:, None]) / n_el
    return az, sin_el, 4.0 / (n_az * n_el)


def secondary(height, normals, emitted, *, object_mask=None, rho_d=1.0, specular=None,
              bounces=1, samples=DEFAULT_SAMPLES, bias=1e-3, engine=None):
    """Secondary light on a height field, one or two bounces.

    Parameters
    ----------
    height : (H, W) float
        Heights in pixel units; the whole field occludes (set pixels that should not
        to a low background first).
    normals : (H, W, 3) float
        Unit normals.
    emitted : (k, H, W) float32
        Diffuse light leaving every point under light i, in image units (the direct
        diffuse image ``mu rho_d (s.n)`` with shadows); 0 where nothing is emitted.
    object_mask : (H, W) bool, optional
        Receivers; the result is 0 outside. Default: every pixel.
    rho_d : float or (H, W)
        Diffuse albedo of the receivers (and of the emitters in the second bounce).
    specular : Specular, optional
        Specular reflectance: adds the specular emission of directly lit points
        towards each receiver and the receivers' specular response. None: Lambert.
    bounces : {1, 2}
    samples : int
        Azimuths of the direction set (>= 4); cost grows as samples^2.
    bias : float
        An occluder must rise more than ``bias`` (pixel-height units) above a ray.
    engine : {None, "numba", "numpy"}
        The compiled kernel (numba) or the vectorised numpy fallback; None: numba
        when installed. Both compute the same quadrature.

    Returns
    -------
    (k, H, W) float32
        Secondary light in image units (all requested bounces).
    """
    h = np.ascontiguousarray(height, dtype=np.float32)
    H, W = h.shape
    n = np.ascontiguousarray(normals, dtype=np.float32).reshape(H, W, 3)
    E = np.asarray(emitted, dtype=np.float32)
    object_mask = np.ones((H, W), bool) if object_mask is None else np.asarray(object_mask, bool)
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 4:
        raise PsbenchError(f"samples must be an integer >= 4, got {samples!r}")
    if bounces not in (1, 2):
        raise PsbenchError(f"bounces must be 1 or 2, got {bounces!r}")
    rho_d = rho_d if np.ndim(rho_d) == 0 else np.asarray(rho_d, np.float32)
    geo = _Geometry(h, n, object_mask, int(samples), float(bias))
    if engine not in (None, "numba", "numpy"):
        raise PsbenchError(f"engine={engine!r} is not known; valid choices: numba, numpy")
    cos1, spec1 = geo.gather(E, specular, engine=engine)
    out = _combine(cos1, spec1, rho_d, specular)
    if bounces == 2:
        emit2 = cos1 * (rho_d if np.ndim(rho_d) == 0 else rho_d[None])
        emit2 *= object_mask[None]
        cos2, spec2 = geo.gather(emit2, specular, emit_specular=False, engine=engine)
        out += _combine(cos2, spec2, rho_d, specular)
    out *= object_mask[None]
    return out


def _combine(acc_cos, acc_spec, rho_d, specular):
    out = acc_cos * (np.float32(rho_d) if np.ndim(rho_d) == 0 else rho_d[None])
    if acc_spec is not None:
        rs = specular.rho_s
        out += acc_spec * (np.float32(rs) if np.ndim(rs) == 0 else np.asarray(rs, np.float32)[None])
    return out


def _max_slope(h):
    """Upper bound of the slope of the bilinear height field along any direction."""
    sx = float(np.abs(np.diff(h, axis=1)).max()) if h.shape[1] > 1 else 0.0
    sy = float(np.abs(np.diff(h, axis=0)).max()) if h.shape[0] > 1 else 0.0
    return math.hypot(sx, sy)


class _Shear:
    """The sheared working grid of one azimuth (columns = ray ground tracks)."""

    def __init__(self, H, W, phi):
        ux, uy = math.cos(phi), math.sin(phi)
        ac, ar = ux, -uy  # image (col, row) direction of travel
        self.cols = abs(ac) >= abs(ar)  # march along columns
        if self.cols:
            L, La, step = W, H, ar / abs(ac)  # across (row) change per step
            self.start = 0 if ac > 0 else W - 1
            self.sgn = 1 if ac > 0 else -1
        else:
            L, La, step = H, W, ac / abs(ar)
            self.start = 0 if ar > 0 else H - 1
            self.sgn = 1 if ar > 0 else -1
        self.L, self.La, self.step = L, La, step
        self.steplen = 1.0 / max(abs(ux), abs(uy))
        lo, hi = min(0.0, step * (L - 1)), max(0.0, step * (L - 1))
        self.j0 = int(math.floor(-1.0 - hi))
        self.nq = int(math.ceil(La - lo)) - self.j0 + 1
        self.H, self.W = H, W

    def source(self, ja, jb):
        """For working columns [ja, jb): (march index (L,), across position (L, n))."""
        rho = np.arange(self.L)
        base = rho * self.step + self.j0  # across position of column 0
        across = base[:, None] + np.arange(ja, jb)[None, :]
        line = self.start + self.sgn * rho  # march-axis pixel of each working row
        return line, across

    def back(self):
        """Per pixel (flat, row-major): working row, fractional working column."""
        H, W = self.H, self.W
        r = np.arange(H)[:, None]
        c = np.arange(W)[None, :]
        if self.cols:
            line, across = c, r
        else:
            line, across = r, c
        rho = (line - self.start) * self.sgn
        j = across - (rho * self.step + self.j0)
        rho, j = np.broadcast_arrays(rho, j)
        return rho.ravel(), j.ravel()


class _Geometry:
    """Light-independent state of one height field; :meth:`gather` integrates."""

    def __init__(self, h, n, object_mask, samples, bias):
        self.h, self.n, self.object_mask, self.bias = h, n, object_mask, np.float32(bias)
        self.H, self.W = h.shape
        self.az, sin_el, self.w = directions(samples)
        slope = _max_slope(h)
        nz = np.clip(n[..., 2][object_mask], -1.0, 1.0) if object_mask.any() else np.ones(1)
        tan_zen = float(np.max(np.sqrt(np.maximum(1.0 - nz * nz, 0.0)) / np.maximum(nz, 1e-6)))
        el = np.arcsin(sin_el)
        # rising rays steeper than any slope hit nothing; falling rays steeper than
        # every tangent plane reach no receiver
        keep = np.where(el > 0, np.tan(el) < slope * 1.0001, np.tan(-el) < tan_zen)
        self.el = [e[kp] for e, kp in zip(el, keep)]
        pad = 2
        self.pad = pad
        self.hp = np.pad(h, pad, mode="edge")
        inside = np.zeros((self.H + 2 * pad, self.W + 2 * pad), bool)
        inside[pad:-pad, pad:-pad] = True
        self.inside = inside
        self.np_ = np.pad(n, ((pad, pad), (pad, pad), (0, 0)), mode="edge").reshape(-1, 3)
        self.mp = np.pad(object_mask.astype(np.float32), pad).ravel()

    # -- resampling onto the working grid --------------------------------------------
    def _lerp_index(self, sh, ja, jb):
        """Flat indices (into the padded image) of the two across-neighbours of every
        working sample of columns [ja, jb), their weight, and the across position."""
        line, across = sh.source(ja, jb)
        a0 = np.floor(across)
        t = (across - a0).astype(np.float32)
        lim = (sh.La + 2 * self.pad - 2)
        i0 = np.clip(a0.astype(np.int64) + self.pad, 0, lim)
        i1 = i0 + 1
        lp = (line + self.pad)[:, None]
        Wp = self.W + 2 * self.pad
        if sh.cols:
            f0, f1 = i0 * Wp + lp, i1 * Wp + lp
        else:
            f0, f1 = lp * Wp + i0, lp * Wp + i1
        return f0.ravel(), f1.ravel(), t.ravel(), across

    def gather(self, E, specular, *, emit_specular=True, engine=None):
        """Sum over directions of (emitted light of the hit point) x (cos at the receiver),
        and x (receiver's specular lobe) when ``specular``; each (k, H, W) float32 (the
        second None without specular). ``engine``: "numba", "numpy" or None (numba when
        it is installed)."""
        k = E.shape[0]
        H, W, pad = self.H, self.W, self.pad
        kern = _kernel() if engine in (None, "numba") else None
        if engine == "numba" and kern is None:
            raise PsbenchError("engine='numba' needs numba installed (pip install numba)")
        Ep = np.pad(np.moveaxis(E, 0, -1), ((pad, pad), (pad, pad), (0, 0))).reshape(-1, k)
        spec_e = specular if (specular is not None and emit_specular) else None
        Lp = None
        if spec_e is not None:  # lit x rho_s x power, the specular emission's factor
            Lp = np.moveaxis(spec_e.lit, 0, -1).astype(np.float32)
            Lp *= np.asarray(spec_e.power, np.float32)
            rs = spec_e.rho_s
            Lp *= np.float32(rs) if np.ndim(rs) == 0 else np.asarray(rs, np.float32)[..., None]
            Lp = np.pad(Lp, ((pad, pad), (pad, pad), (0, 0))).reshape(-1, k)
        acc_cos = np.zeros((H * W, k), np.float32)
        acc_spec = np.zeros((H * W, k), np.float32) if specular is not None else None
        hp, npd = self.hp.ravel(), self.np_
        for phi, el in zip(self.az, self.el):
            if el.size == 0:
                continue
            sh = _Shear(H, W, phi)
            L, nq = sh.L, sh.nq
            wd = np.stack([np.cos(el) * math.cos(phi), np.cos(el) * math.sin(phi),
                           np.sin(el)], axis=1).astype(np.float32)
            T = (np.tan(el) * sh.steplen).astype(np.float32)
            brho, bj = sh.back()
            bjf = np.floor(bj).astype(np.int64)
            bt = (bj - bjf).astype(np.float32)
            per = max(2, _CHUNK // L)
            for ja in range(0, nq - 1, per):
                jb = min(nq, ja + per + 1)  # one column of overlap for the back-mapping
                nc = jb - ja
                f0, f1, t, across = self._lerp_index(sh, ja, jb)
                m0, m1 = self.mp[f0] > 0, self.mp[f1] > 0
                rec = (m0 & (t < 1)) | (m1 & (t > 0))
                if not rec.any():
                    continue
                ok = ((across >= -0.5) & (across <= sh.La - 0.5)).ravel()
                occ = np.where(ok, hp[f0] * (1 - t) + hp[f1] * t, _NOTHING).astype(np.float32)
                # receivers and normals take their values from the object alone: an origin
                # between an object pixel and a background pixel is the object's
                to = np.where(m0 == m1, t, m1.astype(np.float32))
                org = hp[f0] * (1 - to) + hp[f1] * to
                t1 = to[:, None]
                nrm = npd[f0] * (1 - t1) + npd[f1] * t1  # emission, too, is the object's
                Ac = np.zeros((L, nc, k), np.float32)
                As = np.zeros((L, nc, k), np.float32) if specular is not None else None
                geo = (occ.reshape(L, nc), org.reshape(L, nc), nrm.reshape(L, nc, 3),
                       rec.reshape(L, nc))
                if kern is not None:
                    self._numba(kern, specular, spec_e, *geo, f0.reshape(L, nc),
                                f1.reshape(L, nc), to.reshape(L, nc), Ep, Lp, wd, T, Ac, As)
                    kern.backmap(Ac, brho, bjf, bt, ja, jb, acc_cos)
                    if As is not None:
                        kern.backmap(As, brho, bjf, bt, ja, jb, acc_spec)
                    continue
                Ec = Ep[f0] * (1 - t1) + Ep[f1] * t1
                Lc = None if Lp is None else Lp[f0] * (1 - t1) + Lp[f1] * t1
                from ._interreflect_numpy import run
                run(self, specular, spec_e, *geo, Ec.reshape(L, nc, k), Lc, wd, T,
                    Ac.reshape(-1, k), None if As is None else As.reshape(-1, k))
                # back to the pixels whose left working neighbour lies in [ja, jb - 1)
                sel = np.flatnonzero((bjf >= ja) & (bjf < jb - 1))
                i0 = brho[sel] * nc + (bjf[sel] - ja)
                tt = bt[sel][:, None]
                Af = Ac.reshape(-1, k)
                acc_cos[sel] += Af[i0] * (1 - tt) + Af[i0 + 1] * tt
                if As is not None:
                    Sf = As.reshape(-1, k)
                    acc_spec[sel] += Sf[i0] * (1 - tt) + Sf[i0 + 1] * tt
        out_c = np.ascontiguousarray(acc_cos.T).reshape(k, H, W)
        out_s = None if acc_spec is None else np.ascontiguousarray(acc_spec.T).reshape(k, H, W)
        return out_c, out_s

    def _numba(self, kern, specular, spec_e, occ, org, nrm, rec, f0, f1, ft, Ep, Lp, wd, T,
               Ac, As):
        k = Ep.shape[1]
        codes = {"ts": 1, "phong": 2}
        emit = codes[spec_e.model] if spec_e is not None else 0
        recv = codes[specular.model] if specular is not None else 0
        etab = kern.lobe_table(spec_e.model, spec_e.m, spec_e.phong_m) if emit else \
            np.zeros(2, np.float32)
        rtab = kern.lobe_table(specular.model, specular.m, specular.phong_m) if recv else etab
        if emit == 1:
            hv = np.asarray(spec_e.directions, np.float32)[None] - wd[:, None, :]
            hv /= np.maximum(np.linalg.norm(hv, axis=2, keepdims=True), 1e-12)
        else:
            hv = np.zeros((len(T), k, 3), np.float32)
        sd = np.asarray(spec_e.directions if spec_e is not None else np.zeros((k, 3)), np.float32)
        kern.chunk(occ, org, np.ascontiguousarray(nrm), rec, f0, f1, ft, Ep,
                   Lp if Lp is not None else np.zeros((1, 1), np.float32),
                   np.ascontiguousarray(hv), sd, emit, etab, recv, rtab, T, wd,
                   np.float32(self.w), self.bias, Ac,
                   As if As is not None else np.zeros((1, 1, 1), np.float32))


def _kernel():
    """The compiled kernel module, or None without numba."""
    try:
        from . import _interreflect_kernel
    except ImportError:
        return None
    return _interreflect_kernel


def check_bounces(samples, positions, perspective, shadows):
    """Refuse what :func:`add_bounces` does not model (called by ``render``)."""
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or samples < 4:
        raise PsbenchError(f"bounce_samples must be an integer >= 4, got {samples!r}")
    if positions is not None:
        raise PsbenchError("bounces > 0 needs distant lights; near lights (light_positions) "
                           "are not supported with interreflections")
    if perspective is not None:
        raise PsbenchError("bounces > 0 needs the orthographic camera (perspective=None)")
    if isinstance(shadows, str) and shadows == "none":
        raise PsbenchError("bounces > 0 cannot be combined with shadows='none' (unclamped, "
                           "negative light has no interreflection)")


def add_bounces(scene, height, object_mask, normals, *, bounces, samples, noise, seed, model,
                rho_d, rho_s, m, phong_m):
    """Add interreflections to a noiseless, unquantised direct ``scene`` of
    :func:`psbench.render` (arguments validated there; it quantises afterwards).

    The secondary light is added to the clean direct images, then noise follows
    exactly :func:`psbench.render`'s rule (same seed, same draws; sigma relative to
    the range of the clean image *with* secondary light). Ground truth
    ``highlight``/``self_shadow``/``cast_shadow`` stays that of the direct light;
    ``secondary_fraction`` = secondary / clean total (0 where the total is 0).
    """
    from dataclasses import replace

    lay = scene.lights
    images = scene.images  # clean direct light, ours to modify
    spec = None
    if model == "lambert" or (np.ndim(rho_s) == 0 and float(rho_s) == 0.0):
        diffuse = images if model == "lambert" else scene.diffuse
    else:
        diffuse = scene.diffuse
        lit = ~(scene.self_shadow | scene.cast_shadow)
        lit &= object_mask[None]
        spec = Specular(model, rho_s if np.ndim(rho_s) == 0 else np.asarray(rho_s, np.float32),
                        float(m), float(phong_m), np.asarray(lay.directions, np.float64),
                        np.asarray(lay.power, np.float64), lit)
    sec = secondary(height, normals, diffuse, object_mask=object_mask, rho_d=rho_d, specular=spec,
                    bounces=bounces, samples=samples)
    images += sec
    frac = np.zeros_like(sec)
    np.divide(sec, images, out=frac, where=images > 0)
    k, H, W = images.shape
    full = bool(object_mask.all())
    drange = np.zeros(k, np.float32)
    sigma = np.zeros(k, np.float32)
    rng = np.random.default_rng(seed)
    z = np.empty((H, W), np.float32) if noise > 0 else None
    for i in range(k):  # the noise rule of psbench.render, on the total clean image
        img = images[i]
        hi = float(img.max()) if full else float(np.max(img, where=object_mask, initial=-np.inf))
        lo = float(img.min()) if full else float(np.min(img, where=object_mask, initial=np.inf))
        drange[i] = hi - lo if np.isfinite(hi) else 0.0
        if z is not None:
            sigma[i] = np.float32(noise * drange[i])
            rng.standard_normal(dtype=np.float32, out=z)
            z *= sigma[i]
            if not full:
                z *= object_mask
            img += z
    out = replace(scene, images=images, noise=float(noise), sigma=sigma, dynamic_range=drange,
                  bounces=int(bounces), _cache={})
    out._cache["secondary"] = sec
    out._cache["secondary_fraction"] = frac
    return out
