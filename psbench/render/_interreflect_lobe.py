"""The specular lobes of the interreflection code (a leaf module: the renderer's
quadratures and the brute-force reference share it)."""
from __future__ import annotations

import numpy as np

__all__ = ["lobe"]


def lobe(model, c, m, phong_m):
    """Specular lobe from c = n.h (TS) or c = r.v (Phong), in place on float32 c."""
    if model == "ts":
        np.clip(c, -1.0, 1.0, out=c)
        np.arccos(c, out=c)
        c *= np.float32(m)
        np.square(c, out=c)
        np.negative(c, out=c)
        return np.exp(c, out=c)
    np.maximum(c, 0.0, out=c)
    return np.power(c, np.float32(phong_m), out=c)
