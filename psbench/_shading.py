"""Per-light shading for :func:`psbench.render.render`: Lambert, Phong, Torrance–Sparrow.

One :class:`Shader` holds a surface's normals and the light layout and returns, light
by light, the diffuse and specular planes (float32, (H, W)) in reused work buffers, so
that a 2048² stack is shaded without a fresh 16 MB temporary per operation. Shadows,
noise and quantisation are applied by :func:`psbench.render.render`.
"""
from __future__ import annotations

import numpy as np

__all__ = ["Shader"]


class Shader:
    """Per-light shading of one surface; float32 (H, W) planes."""

    def __init__(self, height, object_mask, normals, lay, model, rho_d, rho_s, m, phong_m,
                 positions, falloff, perspective, clamp=True):
        self.object_mask = object_mask
        self.clamp = clamp
        self._t = None  # work buffers, allocated on first use
        self.lay = lay
        self.model = model
        self.rho_d, self.rho_s = rho_d, rho_s
        self.m, self.phong_m = np.float32(m), np.float32(phong_m)
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
        if self.model != "lambert":
            vx, vy, vz = self.view if self.view is not None else (0.0, 0.0, 1.0)
            if self.model == "ts":
                hx, hy, hz = dx + vx, dy + vy, dz + vz
                hn = np.sqrt(hx * hx + hy * hy + hz * hz)
                if np.ndim(hn) == 0:  # constant bisector n_h
                    c = self._dot(hx / hn, hy / hn, hz / hn, self._sp)
                else:
                    c = self._dot(hx, hy, hz, self._sp)
                    c /= hn
                np.clip(c, -1.0, 1.0, out=c)
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
