"""Sh: shadow mask (Section 3.3.2.5), a global normal mask.

The current normals are integrated into heights (``integrator``); each light's
shadow map of those heights gives the cast shadows (``sh_bias``). Section 3.3.2.5 says
Sh "works on both" cast and self shadows, so s.n <= 0 is masked too.
"""
from __future__ import annotations

import numpy as np

from ..._shared.deprecation import renamed_args
from ...registry import Mask
from .. import kernel
from .ss import ss

__all__ = ["sh_maps", "sh", "lit_and_unoccluded", "apply", "MASK"]


@renamed_args(renamed={"method": "integrator"})
def sh_maps(normals, directions, object_mask=None, *, bias=None, integrator="poisson"):
    """Cast-shadow maps of the heights integrated from ``normals``.

    Parameters
    ----------
    normals : (H, W, 3) float32
    directions : (k, 3)
    object_mask : (H, W) bool, optional

    Returns
    -------
    occluded : (k, H, W) bool
        True where light i is blocked by another part of the integrated surface.
    height : (H, W) float32
    """
    from ...integrate.poisson import integrate
    from ...render.shadowmap import shadow_map

    height = integrate(normals, object_mask=object_mask, integrator=integrator)
    kw = {} if bias is None else {"bias": bias}
    occ = shadow_map(height, np.asarray(directions, dtype=np.float64), object_mask=object_mask, **kw)
    return np.asarray(occ, dtype=bool), height


def sh(normals, b, S, directions, object_mask=None, **kw):
    """Valid where not cast-shadowed and s . n > 0.

    Returns
    -------
    valid : (k, H, W) bool
    height : (H, W) float32
    """
    occ, height = sh_maps(normals, directions, object_mask, **kw)
    return lit_and_unoccluded(b, S, occ, out=occ), height


#: pixels per block of :func:`lit_and_unoccluded` (a (k, block) float32 block stays in
#: cache; at 2048 x 2048 x 16 the whole s . b array would be 256 MB)
_BLOCK = 1 << 15


def lit_and_unoccluded(b, S, occluded, *, out=None):
    """``(s_i . b > 0) & ~occluded`` (the SS test and the cast shadows), block by block.

    Same values as ``ss(b, S) & ~occluded``: each block's s . b is the same float32
    product, only never held whole.

    Parameters
    ----------
    b : (H, W, 3) float32
    S : (k, 3)
    occluded : (k, H, W) bool
    out : (k, H, W) bool, optional
        May be ``occluded`` itself (each block is read before it is written).

    Returns
    -------
    valid : (k, H, W) bool
    """
    k = occluded.shape[0]
    S32 = np.asarray(S, dtype=np.float32)
    B = b.reshape(-1, 3)
    occ = occluded.reshape(k, -1)
    res = np.empty(occluded.shape, dtype=bool) if out is None else out
    flat = res.reshape(k, -1)
    lam = np.empty((k, _BLOCK), dtype=np.float32)
    lit = np.empty((k, _BLOCK), dtype=bool)
    for lo in range(0, B.shape[0], _BLOCK):
        hi = min(B.shape[0], lo + _BLOCK)
        n = hi - lo
        np.matmul(S32, B[lo:hi].T, out=lam[:, :n])
        np.greater(lam[:, :n], 0, out=lit[:, :n])
        np.greater(lit[:, :n], occ[:, lo:hi], out=flat[:, lo:hi])   # lit and not occluded
    return res


def apply(images, b, ctx):
    """Global normal stage: integrates the current normals (full (H, W, 3) arrays)."""
    n, _ = kernel.split(b)
    o = ctx.options
    valid, _ = sh(n, b, ctx.S32, ctx.directions, ctx.region, bias=o.sh_bias,
                  integrator=o.integrator)
    return valid


MASK = Mask("Sh", "normal", apply, local=False,
            help="cast and self shadows from shadow maps of the integrated normals (Section 3.3.2.5)")
