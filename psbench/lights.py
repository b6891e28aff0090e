"""Light layouts: thesis ring notation (``45x8``, ``30x8+60x8``), explicit lists, cond(S).

Directions are unit vectors from the surface towards the light in psbench's frame
(x right, y up, camera at +z). Zenith is measured from +z, polar angle
counter-clockwise from +x, both in degrees.

Ring geometry (Table 5.4): the ``n`` sources of one ring are equally spaced in polar
angle, ``360/n`` apart, starting at polar 0 for ring 0. Ring ``r`` (of ``R`` rings) is
rotated by ``r * (360/n_r) / R`` so that, seen from above, consecutive sources of the
whole layout keep equal polar distances (e.g. ``30x8+60x8``: ring 0 at 0, 45, ...,
ring 1 at 22.5, 67.5, ...).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from ._shared.checks import PsbenchError
from ._shared.deprecation import renamed_args

__all__ = ["Layout", "layout", "cond", "ring_spec"]

_RING = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*[xX]\s*(\d+)\s*$")


@dataclass(frozen=True, eq=False)
class Layout:
    """A set of k distant light sources.

    Attributes
    ----------
    directions : (k, 3) float64
        Unit vectors towards each light.
    power : (k,) float64
        Light powers mu (illumination vector s = mu * d, Eq. 2.16).
    ring : (k,) int
        Ring id of each light (0 for an explicit list unless given).
    zenith, polar : (k,) float64
        Angles of each light in degrees.
    name : str
        Thesis notation (``30x8+60x8``) or ``custom``.
    """

    directions: np.ndarray
    power: np.ndarray
    ring: np.ndarray
    zenith: np.ndarray
    polar: np.ndarray
    name: str = "custom"
    positions: np.ndarray | None = field(default=None)

    def __len__(self) -> int:
        return int(self.directions.shape[0])

    @property
    def k(self) -> int:
        """Number of lights."""
        return len(self)

    @property
    def S(self) -> np.ndarray:
        """(k, 3) illumination matrix, rows s_i = mu_i d_i."""
        return self.directions * self.power[:, None]

    @property
    def n_rings(self) -> int:
        return int(np.unique(self.ring).size)

    @property
    def ring_zeniths(self) -> np.ndarray:
        """Mean zenith (degrees) of each ring, ordered by ring id."""
        ids = np.unique(self.ring)
        return np.array([self.zenith[self.ring == r].mean() for r in ids])

    def rings(self) -> list[np.ndarray]:
        """Index arrays of the lights of each ring, ordered by ring id."""
        return [np.flatnonzero(self.ring == r) for r in np.unique(self.ring)]

    def subset(self, index) -> "Layout":
        """A new layout made of the lights ``index`` (ints or bool mask)."""
        idx = np.arange(self.k)[index]
        pos = None if self.positions is None else self.positions[idx]
        return Layout(self.directions[idx], self.power[idx], self.ring[idx],
                      self.zenith[idx], self.polar[idx], name=f"{self.name}[subset]",
                      positions=pos)

    def cond(self) -> float:
        """Condition number of S (Eq. 2.23)."""
        return cond(self.S)

    def __repr__(self) -> str:
        return f"Layout({self.name!r}, k={self.k}, rings={self.n_rings})"


def cond(S) -> float:
    """Condition value sigma_max / sigma_min of an illumination matrix (Eq. 2.23).

    Parameters
    ----------
    S : (k, 3) array_like or Layout
    """
    if isinstance(S, Layout):
        S = S.S
    try:
        S = np.asarray(S, dtype=np.float64)
    except (TypeError, ValueError):
        raise PsbenchError(f"S must be a (k, 3) array of numbers or a Layout, got "
                           f"{type(S).__name__}") from None
    if S.ndim != 2 or S.shape[1] != 3 or S.shape[0] < 1:
        raise PsbenchError(f"S must have shape (k, 3), got {S.shape}")
    if not np.isfinite(S).all():
        raise PsbenchError("S holds NaN/inf values")
    sv = np.linalg.svd(S, compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")


def _angles(d):
    zen = np.degrees(np.arccos(np.clip(d[:, 2], -1.0, 1.0)))
    pol = np.degrees(np.arctan2(d[:, 1], d[:, 0])) % 360.0
    return zen, pol


def _dirs(zen, pol):
    z, p = np.radians(zen), np.radians(pol)
    return np.stack([np.sin(z) * np.cos(p), np.sin(z) * np.sin(p), np.cos(z)], axis=1)


def ring_spec(spec: str) -> list[tuple[float, int]]:
    """Parse thesis notation into ``[(zenith, count), ...]``."""
    if not isinstance(spec, str) or not spec.strip():
        raise PsbenchError(f"lights={spec!r}: expected ring notation like '45x8' or '30x8+60x8'")
    rings = []
    for part in spec.split("+"):
        m = _RING.match(part)
        if not m:
            raise PsbenchError(
                f"lights={spec!r}: ring {part.strip()!r} is malformed; each ring is "
                "'<zenith degrees>x<count>', e.g. '45x8', rings joined by '+'")
        zen, n = float(m.group(1)), int(m.group(2))
        if not 0.0 <= zen < 90.0:
            raise PsbenchError(f"lights={spec!r}: zenith {zen:g} must be in [0, 90) degrees")
        if n < 1:
            raise PsbenchError(f"lights={spec!r}: ring {part.strip()!r} needs at least 1 light")
        rings.append((zen, n))
    return rings


def _check_S(directions, power, name):
    k = directions.shape[0]
    if k < 3:
        raise PsbenchError(f"{name}: photometric stereo needs at least 3 lights, got {k}")
    c = cond(directions * power[:, None])
    if not np.isfinite(c) or c > 1e8:
        raise PsbenchError(
            f"{name}: the light directions are degenerate (S is singular, cond={c:.3g}); "
            "lights must not be coplanar with the origin or duplicated, e.g. a ring at zenith 0")


@renamed_args(positional=("power",))
def layout(spec, *, power=None, ring=None, positions=None) -> Layout:
    """Build a :class:`Layout`.

    Parameters
    ----------
    spec : str, (k, 3) array_like, or Layout
        Ring notation (``"45x8"``, ``"30x8+60x8"``, ``"30x4+45x4+60x4"``), explicit
        directions (normalised here), or an existing layout (returned, with
        ``power`` applied if given).
    power : float or (k,) array_like, optional
        Light powers mu; default 1.
    ring : (k,) array_like of int, optional
        Ring ids for explicit directions (default: grouped by equal zenith, 0.5 deg).
    positions : (k, 3) array_like, optional
        Finite light positions (pixel units) for near-light rendering.
    """
    if isinstance(spec, Layout):
        if power is None:
            return spec
        p = _power(power, spec.k)
        return Layout(spec.directions, p, spec.ring, spec.zenith, spec.polar, spec.name,
                      spec.positions)
    if isinstance(spec, str):
        rings = ring_spec(spec)
        R = len(rings)
        zen, pol, rid = [], [], []
        for r, (z, n) in enumerate(rings):
            step = 360.0 / n
            offset = r * step / R
            zen += [z] * n
            pol += list((offset + step * np.arange(n)) % 360.0)
            rid += [r] * n
        zen, pol = np.array(zen, dtype=float), np.array(pol, dtype=float)
        d = _dirs(zen, pol)
        name = "+".join(f"{z:g}x{n}" for z, n in rings)
        p = _power(power, d.shape[0])
        _check_S(d, p, f"lights={spec!r}")
        return Layout(d, p, np.array(rid, dtype=int), zen, pol, name)
    d = np.asarray(spec, dtype=np.float64)
    if d.ndim != 2 or d.shape[1] != 3:
        raise PsbenchError(f"lights must be ring notation or a (k, 3) array, got shape {d.shape}")
    if not np.isfinite(d).all():
        raise PsbenchError("lights holds NaN/inf values")
    norms = np.linalg.norm(d, axis=1)
    if (norms < 1e-12).any():
        raise PsbenchError(f"lights: direction(s) {np.flatnonzero(norms < 1e-12).tolist()} are zero vectors")
    d = d / norms[:, None]
    if (d[:, 2] < 0).any():
        raise PsbenchError(
            f"lights: direction(s) {np.flatnonzero(d[:, 2] < 0).tolist()} point away from the camera (z < 0)")
    p = _power(power, d.shape[0])
    _check_S(d, p, "lights")
    zen, pol = _angles(d)
    if ring is None:
        rid = np.zeros(len(zen), dtype=int)
        order = np.unique(np.round(zen / 0.5) * 0.5)
        for i, z in enumerate(order):
            rid[np.isclose(np.round(zen / 0.5) * 0.5, z)] = i
    else:
        rid = np.asarray(ring, dtype=int)
        if rid.shape != (d.shape[0],):
            raise PsbenchError(f"ring must have shape ({d.shape[0]},), got {rid.shape}")
    pos = None if positions is None else np.asarray(positions, dtype=np.float64)
    if pos is not None and pos.shape != d.shape:
        raise PsbenchError(f"positions must have shape {d.shape}, got {pos.shape}")
    return Layout(d, p, rid, zen, pol, "custom", pos)


#: light powers psbench accepts: images (mu rho s.n) and albedos (I / mu) stay float32
POWER_RANGE = (1e-30, 1e30)


def _power(power, k):
    if power is None:
        return np.ones(k)
    p = np.broadcast_to(np.asarray(power, dtype=np.float64), (k,)).copy() \
        if np.ndim(power) == 0 else np.asarray(power, dtype=np.float64)
    if p.shape != (k,):
        raise PsbenchError(f"power must be a scalar or have shape ({k},), got {p.shape}")
    if not np.isfinite(p).all() or (p <= 0).any():
        raise PsbenchError("power must be finite and > 0 for every light")
    if (p < POWER_RANGE[0]).any() or (p > POWER_RANGE[1]).any():
        raise PsbenchError(f"power must be within {POWER_RANGE[0]:g}..{POWER_RANGE[1]:g} (images "
                           f"and albedos are float32), got {p.min():g}..{p.max():g}; a common "
                           "factor does not change the normals: rescale the powers")
    return p
