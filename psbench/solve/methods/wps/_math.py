"""Inline arccos and the Eq. 4.15 sigmoid for the WPS kernel
(:mod:`psbench.solve.methods.wps._kernel`).

Calls into the C math library would stop the SIMD code of the kernel's pixel loops (and
cost ~12x more at 512^2), so both are evaluated from their Taylor series (accurate to
~1e-12, far below float32's resolution).
"""
from __future__ import annotations

import math
from math import factorial

from numba import njit

__all__ = ["DEG", "acos", "sig"]

DEG = 180.0 / math.pi
# asin(s) = s + s z Q(z), z = s^2 <= 1/4: Taylor coefficients of Q (12 terms: error < 1e-10)
_Q = tuple(factorial(2 * m + 2) / (4 ** (m + 1) * factorial(m + 1) ** 2 * (2 * m + 3))
           for m in range(12))
# exp(r) for |r| <= 100 / 256 (11 terms: error < 1e-9 after the 8 squarings)
_E = tuple(1.0 / factorial(m) for m in range(11))


@njit(cache=True, nogil=True, error_model="numpy")
def acos(x):
    """arccos on [-1, 1] without a library call (vectorisable; polynomials in Estrin's
    form for short dependency chains)."""
    a = abs(x)
    big = a > 0.5
    z = 0.5 * (1.0 - a) if big else a * a
    s = math.sqrt(z) if big else a
    z2 = z * z
    z4 = z2 * z2
    p0 = (_Q[0] + _Q[1] * z) + (_Q[2] + _Q[3] * z) * z2
    p1 = (_Q[4] + _Q[5] * z) + (_Q[6] + _Q[7] * z) * z2
    p2 = (_Q[8] + _Q[9] * z) + (_Q[10] + _Q[11] * z) * z2
    p = p0 + (p1 + p2 * z4) * z4
    asn = s + s * z * p
    r = 2.0 * asn if big else 0.5 * math.pi - asn
    return r if x >= 0.0 else math.pi - r


@njit(cache=True, nogil=True, error_model="numpy")
def sig(x):
    """Eq. 4.15's sigmoid 1 / (1 + exp(-10 (x - 0.5))); 0 where exp overflows float32, as
    the float32 formula gives."""
    y = -10.0 * (x - 0.5)
    r = min(max(y, -100.0), 100.0) * 0.00390625     # exp(y) = exp(y / 256)^256
    r2 = r * r
    r4 = r2 * r2
    p0 = (_E[0] + _E[1] * r) + (_E[2] + _E[3] * r) * r2
    p1 = (_E[4] + _E[5] * r) + (_E[6] + _E[7] * r) * r2
    p2 = (_E[8] + _E[9] * r) + _E[10] * r2
    p = p0 + (p1 + p2 * r4) * r4
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    p = p * p
    return 0.0 if y > 88.72283935546875 else 1.0 / (1.0 + p)
