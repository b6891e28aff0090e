"""Pieces several masks share: thresholds read by more than one mask, the
reflection test (Re and NL-Re) and the Lambert residual of one evaluation (CS, Hi)."""
from __future__ import annotations

import numpy as np

from ...registry import Threshold
from . import _kernel
from ..thresholds import COUNTS, TABLE_5_2, eq_5_1

__all__ = ["K_LOW", "T_NL", "T_RE", "bisectors", "reflection_valid", "lambert_residual"]

#: lower Th bound (Eq. 3.2); NL's shadow level too
K_LOW = Threshold("k_low", TABLE_5_2["k_low"], (0.0, 1.0), counts=COUNTS,
                  help="Th lower bound, fraction of the dynamic range (Eq. 3.2, Table 5.2)")
#: Lambertian-error threshold of NL and xNL
T_NL = Threshold("t_NL", TABLE_5_2["t_NL"], (0.0, 1e6), counts=COUNTS,
                 help="NL/xNL threshold on the squared Lambertian error (a.I / D)^2 (Table 5.2)")
#: reflection angle of Re (and of NL-Re, xNL's broken patterns), Eq. 5.1
T_RE = Threshold("t_Re", eq_5_1, (0.0, 90.0), per_light=True,
                 help="Re angle to the light/view bisector in degrees (Eq. 5.1 per light)")


def bisectors(directions):
    """Unit bisectors of each light direction and the view vector v = (0, 0, 1), (k, 3)."""
    d = np.asarray(directions, dtype=np.float64)
    h = d + np.array([0.0, 0.0, 1.0])
    return h / np.linalg.norm(h, axis=1, keepdims=True)


def reflection_valid(normals, directions, t_re):
    """Reflection mask (Eq. 3.8, corrected): valid where angle(n, h_i) >= t_Re.

    Parameters
    ----------
    normals : (*P, 3) unit normals
    directions : (k, 3) light directions
    t_re : float or (k,) degrees

    Returns
    -------
    valid : (k, *P) bool
    """
    H = bisectors(directions)
    k = H.shape[0]
    c = np.cos(np.radians(np.broadcast_to(np.asarray(t_re, dtype=float), (k,))))
    P = normals.shape[:-1]
    n = np.ascontiguousarray(normals, dtype=np.float32).reshape(-1, 3)
    out = np.empty((k, n.shape[0]), dtype=bool)
    _kernel.within_cos(n, H.astype(np.float32), c.astype(np.float32), out)
    return out.reshape((k,) + P)


def lambert_residual(ctx, images, b):
    """Signed residuals i - rho s.n of the arrays of the current evaluation, computed
    once per evaluation (``ctx.cache``) however many masks read them."""
    r = ctx.cache.get("lambert_residual")
    if r is None:
        k = images.shape[0]
        I2 = np.ascontiguousarray(images, dtype=np.float32).reshape(k, -1)
        r = np.empty(I2.shape, dtype=np.float32)
        _kernel.lambert_residuals(I2, np.ascontiguousarray(b, dtype=np.float32).reshape(-1, 3),
                                  np.asarray(ctx.S32, dtype=np.float32), r)
        r = ctx.cache["lambert_residual"] = r.reshape(images.shape)
    return r
