"""Per-light shading for :func:`psbench.render.render`: Lambert, Phong, Torrance–Sparrow, GGX.

One :class:`Shader` holds a surface's normals and the light layout and returns, light
by light, the diffuse and specular planes (float32, (H, W)) in reused work buffers, so
that a 2048² stack is shaded without a fresh 16 MB temporary per operation. Shadows,
noise and quantisation are applied by :func:`psbench.render.render`.
"""
from __future__ import annotations

import numpy as np

from .._shared.checks import PsbenchError, choice

#: ground-truth highlight definitions (see :func:`render`, ``highlight``)
HIGHLIGHT_RULES = ("cone", "range")
#: default half-angle (degrees) of the reflection cone of ``highlight="cone"``
HIGHLIGHT_ANGLE = 12.0
#: default fraction of the image range of ``highlight="range"``
HIGHLIGHT_FRACTION = 0.1

__all__ = ["Shader", "highlight_plane", "highlight_rule", "highlight_truth", "lobe"]


class Shader:
    """Per-light shading of one surface; float32 (H, W) planes."""

    def __init__(self, height, object_mask, normals, lay, model, rho_d, rho_s, m, phong_m,
                 positions, falloff, perspective, clamp=True, half_cos=False, roughness=0.3,
                 f0=0.04):
        self.object_mask = object_mask
        self.roughness, self.f0 = roughness, f0   # GGX (psbench.render._ggx)
        self.clamp = clamp
        #: keep cos(n, n_h) of the last light in ``self.cos_h`` (the reflection-cone
        #: highlight truth needs it for every model)
        self.want_half = half_cos
        self.cos_h = None
        self._t = None  # work buffers, allocated on first use
        self.lay = lay
        self.model = model
        self.rho_d, self.rho_s = rho_d, rho_s
        self.m, self.phong_m = np.asarray(m, np.float32), np.asarray(phong_m, np.float32)
        self.positions = positions
        self.falloff = falloff
        self.perspective = perspective
        self.nx = np.ascontiguousarray(normals[..., 0])
        self.ny = np.ascontiguousarray(normals[..., 1])
        self.nz = np.ascontiguousarray(normals[..., 2])
        H, W = object_mask.shape
        self.x = (np.arange(W, dtype=np.float32) - np.float32((W - 1) / 2))[None, :]
        self.y = (np.float32((H - 1) / 2) - np.arange(H, dtype=np.float32))[:, None]
        self.h = height
        self.view = None
        if perspective is not None:
            vz = np.float32(perspective) - height
            vx = np.broadcast_to(-self.x, (H, W))
            vy = np.broadcast_to(-self.y, (H, W))
            inv = 1.0 / np.sqrt(vx * vx + vy * vy + vz * vz)
            self.view = (vx * inv, vy * inv, vz * inv)

    def _dot(self, ax, ay, az, out):
        """out = n . (ax, ay, az) (scalars or (H, W) planes), without temporaries."""
        t = self._t
        np.multiply(self.nx, ax, out=out)
        np.multiply(self.ny, ay, out=t)
        out += t
        np.multiply(self.nz, az, out=t)
        out += t
        return out

    def light(self, i):
        """Return (diffuse, specular or None, lit) for light i, shadows not applied
        except that both terms are meaningless where ``lit`` is False.

        The arrays are work buffers of this shader, valid until the next call
        (fresh 16 MB temporaries per operation would cost more in page faults at
        2048^2 than the arithmetic itself).
        """
        if self._t is None:
            shape = self.object_mask.shape
            self._t, self._sn, self._sp = (np.empty(shape, np.float32) for _ in range(3))
            self._lit = np.empty(shape, bool)
        if self.want_half and self.cos_h is None:
            self.cos_h = np.empty(self.object_mask.shape, np.float32)
        mu = float(self.lay.power[i])
        scale = None
        if self.positions is None:
            dx, dy, dz = (float(c) for c in self.lay.directions[i])
        else:
            L = self.positions[i]
            dx = np.float32(L[0]) - self.x
            dy = np.float32(L[1]) - self.y
            dz = np.float32(L[2]) - self.h
            dist2 = dx * dx + dy * dy + dz * dz
            inv = 1.0 / np.sqrt(dist2)
            dx, dy, dz = dx * inv, dy * inv, dz * inv
            if self.falloff:
                scale = np.float32(L @ L) / dist2
        sn = self._dot(dx, dy, dz, self._sn)
        lit = np.greater(sn, 0.0, out=self._lit)
        spec = None
        vx, vy, vz = self.view if self.view is not None else (0.0, 0.0, 1.0)
        if self.model in ("ts", "ggx") or (self.want_half and self.model != "lambert"):
            hx, hy, hz = dx + vx, dy + vy, dz + vz
            hn = np.sqrt(hx * hx + hy * hy + hz * hz)
            if np.ndim(hn) == 0:  # constant bisector n_h
                c = self._dot(hx / hn, hy / hn, hz / hn, self._sp)
            else:
                c = self._dot(hx, hy, hz, self._sp)
                c /= hn
            np.clip(c, -1.0, 1.0, out=c)
            if self.want_half:
                np.copyto(self.cos_h, c)
        if self.model != "lambert":
            if self.model == "ggx":
                from ._ggx import ggx_specular
                nv = self._dot(vx, vy, vz, np.empty_like(sn)) if self.view is not None else self.nz
                vh = (dx * vx + dy * vy + dz * vz + 1.0) / hn   # v.h = (l.v + 1) / |l + v|
                spec = ggx_specular(sn, nv, c, vh, self.roughness, self.f0, out=c)
            elif self.model == "ts":
                a = np.arccos(c, out=c)
                a *= self.m
                np.square(a, out=a)
                np.negative(a, out=a)
                spec = np.exp(a, out=a)
            else:  # phong: r.v = 2 (s.n)(n.v) - s.v
                rv = self._dot(vx, vy, vz, self._sp)
                rv *= sn
                rv *= 2.0
                rv -= dx * vx + dy * vy + dz * vz
                np.maximum(rv, 0.0, out=rv)
                spec = np.power(rv, self.phong_m, out=rv)
            if np.ndim(self.rho_s) == 0:
                spec *= np.float32(mu * float(self.rho_s))
            else:
                spec *= np.float32(mu)
                spec *= self.rho_s
        diff = sn
        if np.ndim(self.rho_d) == 0:
            diff *= np.float32(mu * float(self.rho_d))
        else:
            diff *= np.float32(mu)
            diff *= self.rho_d
        if scale is not None:
            diff *= scale
            if spec is not None:
                spec *= scale
        if not self.clamp:  # shadows="none": nothing is dark
            lit[...] = True
        return diff, spec, lit

    def components(self, dark):
        """Clean diffuse and specular stacks with ``dark`` (k, H, W) set to 0."""
        k = self.lay.k
        H, W = self.object_mask.shape
        diff = np.empty((k, H, W), dtype=np.float32)
        spec = np.zeros((k, H, W), dtype=np.float32)
        for i in range(k):
            d, s, lit = self.light(i)
            off = dark[i] | ~lit | ~self.object_mask
            diff[i] = d
            diff[i][off] = 0.0
            if s is not None:
                spec[i] = s
                spec[i][off] = 0.0
        return diff, spec


def lobe(model, c, m, phong_m):
    """Specular lobe from c = n.h (TS) or c = r.v (Phong), in place on float32 c (the
    interreflection quadratures and their brute-force reference)."""
    if model == "ts":
        np.clip(c, -1.0, 1.0, out=c)
        np.arccos(c, out=c)
        c *= np.float32(m)
        np.square(c, out=c)
        np.negative(c, out=c)
        return np.exp(c, out=c)
    np.maximum(c, 0.0, out=c)
    return np.power(c, np.float32(phong_m), out=c)


def highlight_plane(out, spec, cos_h, keep, *, cos_t=None, threshold=None):
    """Ground-truth highlight of one light into ``out`` (H, W) bool: the reflection cone
    ``cos(n, n_h) > cos_t`` with a specular term (``cos_t``), else the specular term above
    ``threshold``; only where ``keep`` (lit, unshadowed object pixels)."""
    if cos_t is not None:
        np.greater(cos_h, cos_t, out=out)
        out &= spec > 0          # no specular albedo: no highlight
    elif threshold is not None and threshold > 0:
        np.greater(spec, np.float32(threshold), out=out)
    else:
        out[...] = False
        return out
    out &= keep
    return out


def highlight_truth(shader, dark, drange, *, cos_t=None, fraction=None):
    """(k, H, W) bool ground-truth highlight of a rendered scene under another definition
    (``cos_t``: reflection cone; ``fraction``: share of each image's range ``drange``),
    recomputed light by light; ``dark`` (k, H, W) are the scene's shadows."""
    k = shader.lay.k
    out = np.zeros((k,) + shader.object_mask.shape, dtype=bool)
    if shader.model == "lambert":
        return out
    want = shader.want_half
    shader.want_half = cos_t is not None
    try:
        for i in range(k):
            _, spec, lit = shader.light(i)
            keep = lit & ~dark[i] & shader.object_mask
            highlight_plane(out[i], spec, shader.cos_h, keep, cos_t=cos_t,
                            threshold=None if fraction is None else fraction * float(drange[i]))
    finally:
        shader.want_half = want
    return out


def highlight_rule(highlight, angle, fraction):
    """(rule, angle or None, fraction or None) of render's ground-truth highlight options
    (validated; defaults :data:`psbench.render.HIGHLIGHT_ANGLE` / ``HIGHLIGHT_FRACTION``)."""
    if highlight is None:
        highlight = "range" if fraction is not None else "cone"
    rule = choice(highlight, HIGHLIGHT_RULES, "highlight")
    if rule == "cone":
        if fraction is not None:
            raise PsbenchError("highlight_fraction applies to highlight='range'; "
                               "highlight='cone' takes highlight_angle")
        a = HIGHLIGHT_ANGLE if angle is None else _positive(angle, "highlight_angle")
        if a >= 90:
            raise PsbenchError(f"highlight_angle must be in (0, 90) degrees, got {angle!r}")
        return rule, float(a), None
    if angle is not None:
        raise PsbenchError("highlight_angle applies to highlight='cone'; "
                           "highlight='range' takes highlight_fraction")
    f = HIGHLIGHT_FRACTION if fraction is None else _nonneg(fraction, "highlight_fraction")
    return rule, None, float(f)


def _nonneg(value, name):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be a number >= 0, got {value!r}") from None
    if not np.isfinite(v) or v < 0:
        raise PsbenchError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def _positive(value, name):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise PsbenchError(f"{name} must be a number > 0, got {value!r}") from None
    if not np.isfinite(v) or v <= 0:
        raise PsbenchError(f"{name} must be a finite number > 0, got {value!r}")
    return v
