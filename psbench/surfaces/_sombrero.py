"""The sombrero family of thesis Chapter 4: ``z = A sin(r/λ) / (r/λ)``.

On ``[-7200, 7200]²`` with peaks ``A = 1750, 3500, 7000`` (sombrero1, 2, 3) and one
``λ`` (:data:`SOMBRERO_LAMBDA`) for all three, chosen so that sombrero2's largest
surface zenith is 66° (thesis Fig. 4.9). Mapped onto the size × size grid; heights
scaled by ``size / 14400`` into pixel units. The object mask is the whole square.
Analytic normals.
"""
from __future__ import annotations

import math

import numpy as np

from ._surface import Surface, normals_from_slopes, pixel_grid

__all__ = ["SOMBRERO_LAMBDA", "SOMBRERO_PEAKS", "SOMBRERO_HALF", "sombrero_lambda", "sombrero"]

#: Sombrero peaks (thesis units) of sombrero1, sombrero2, sombrero3.
SOMBRERO_PEAKS = {"sombrero1": 1750.0, "sombrero2": 3500.0, "sombrero3": 7000.0}
#: Half width of the sombrero domain [-7200, 7200]² in thesis units.
SOMBRERO_HALF = 7200.0


def _sinc_slope(u):
    """d/du [sin(u)/u]."""
    return (u * math.cos(u) - math.sin(u)) / (u * u)


def _sinc_curv(u):
    """d²/du² [sin(u)/u]."""
    return (-u * u * math.sin(u) - 2.0 * u * math.cos(u) + 2.0 * math.sin(u)) / u ** 3


def sombrero_lambda(max_zenith=66.0, peak=3500.0):
    """Solve for the sombrero length scale λ (thesis units).

    The sombrero ``z = A sin(r/λ)/(r/λ)`` has radial slope ``A/λ · f'(r/λ)``
    with ``f(u) = sin(u)/u``. Its steepest point is the first extremum of
    ``f'``, the root ``u* ≈ 2.0816`` of ``f''(u) = 0`` (found here by
    bisection on [1.5, 3]), where ``|f'(u*)| ≈ 0.43618``. Requiring the
    largest surface zenith of sombrero2 (``A = 3500``) to be 66° (thesis
    Fig. 4.9) gives::

        λ = A |f'(u*)| / tan(66°) ≈ 679.70

    With this λ the steepest ring (r = u* λ ≈ 1415) lies well inside the
    domain, and the maximal zeniths are ≈ 48.3° (sombrero1), 66.0°
    (sombrero2) and 77.4° (sombrero3).
    """
    lo, hi = 1.5, 3.0  # f'' changes sign once on this bracket
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if (_sinc_curv(lo) < 0) == (_sinc_curv(mid) < 0):
            lo = mid
        else:
            hi = mid
    u_star = 0.5 * (lo + hi)
    return peak * abs(_sinc_slope(u_star)) / math.tan(math.radians(max_zenith))


#: One λ (thesis units) for all three sombreros; see :func:`sombrero_lambda` (≈ 679.70).
SOMBRERO_LAMBDA = sombrero_lambda()


def sombrero(name, size):
    """The sombrero ``name`` (a key of :data:`SOMBRERO_PEAKS`) on a size × size grid."""
    peak = SOMBRERO_PEAKS[name]
    lam = SOMBRERO_LAMBDA
    scale = size / (2.0 * SOMBRERO_HALF)      # pixels per thesis unit
    x, y = pixel_grid((size, size))
    X, Y = x / scale, y / scale               # thesis units
    r = np.sqrt(X * X + Y * Y)
    u = r / lam
    z = peak * np.sinc(u / np.pi)             # np.sinc(t) = sin(pi t)/(pi t)
    # slope dz/dr = A/λ f'(u); f'(u) ~ -u/3 near 0
    small = u < 1e-4
    us = np.where(small, 1.0, u)
    fp = np.where(small, -u / 3.0, (us * np.cos(us) - np.sin(us)) / (us * us))
    dzdr = peak / lam * fp
    rs = np.where(r > 0, r, 1.0)
    p = np.where(r > 0, dzdr * X / rs, 0.0)   # dz/dx is scale invariant
    q = np.where(r > 0, dzdr * Y / rs, 0.0)
    object_mask = np.ones((size, size), dtype=bool)
    return Surface(name, (z * scale).astype(np.float32), object_mask, normals_from_slopes(p, q))
