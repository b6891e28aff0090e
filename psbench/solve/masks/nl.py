"""NL: non-Lambert quadruples (Eqs. 3.3-3.6), exactly four images.

``a`` spans the null space of S^T (S is 4x3), normalised to unit L2 norm with
a_1 >= 0; intensities are divided by the mean dynamic range of the four images so
that the Lambertian error ``(a I / R)^2`` and t_NL are scale-free. A failing
quadruple masks its **darkest** observation when that one is below the Th lower
bound (i_min + k_low * range: a shadow), else its **brightest** (a highlight). With Re
in the combination (Barsky's NL-Re) the observation(s) of the failing quadruple
flagged by Re on the first least-squares normals are masked instead of the
brightest, when Re flags any.
"""
from __future__ import annotations

import numpy as np

from ..._shared.checks import PsbenchError
from ...registry import Mask
from .. import kernel
from ._shared import K_LOW, T_NL, T_RE, reflection_valid

__all__ = ["nl_vector", "nl", "apply", "MASK"]


def nl_vector(S):
    """The vector a with a S = 0 (Eq. 3.3) for 4 lights, unit L2 norm, a[0] >= 0."""
    S = np.asarray(S, dtype=np.float64)
    if S.shape != (4, 3):
        raise PsbenchError(f"NL needs exactly 4 lights (S of shape (4, 3)), got {S.shape}")
    _, _, vt = np.linalg.svd(S.T)
    a = vt[-1]
    a = a / np.linalg.norm(a)
    return a if a[0] >= 0 else -a


def nl(images, S, t_nl, *, scale=1.0, shadow_level=None, prefer=None):
    """Non-Lambert quadruple mask (Eqs. 3.3-3.6) for exactly four images.

    Parameters
    ----------
    images : (4, *P) float32
    S : (4, 3)
    t_nl : float
        Threshold on ``(a I / scale)^2``.
    scale : float
        Intensity scale (mean dynamic range), makes t_NL scale-free.
    shadow_level : array broadcastable to images, optional
        Observations below it count as shadows (default: 0, i.e. never).
    prefer : (4, *P) bool, optional
        Observations to mask in failing quadruples instead of the brightest (e.g. the
        Re flags for NL-Re); used where any of them is set and the darkest is not a
        shadow.

    Returns
    -------
    valid : (4, *P) bool
        False at one observation (or the ``prefer`` ones) of each failing quadruple.
    """
    k = images.shape[0]
    if k != 4:
        raise PsbenchError(f"NL needs exactly 4 images, got {k}")
    a = (nl_vector(S) / scale).astype(np.float32)
    e = np.tensordot(a, images, axes=1)
    fail = e * e > np.float32(t_nl)
    valid = np.ones(images.shape, dtype=bool)
    if not fail.any():
        return valid
    shape = images.shape
    flat = images.reshape(4, -1)
    f = fail.reshape(-1)
    cols = np.flatnonzero(f)
    sub = flat[:, cols]
    pick = sub.argmax(axis=0)
    is_shadow = np.zeros(cols.size, dtype=bool)
    if shadow_level is not None:
        lvl = np.broadcast_to(shadow_level, shape).reshape(4, -1)[:, cols]
        dark = sub.argmin(axis=0)
        ar = np.arange(cols.size)
        is_shadow = sub[dark, ar] < lvl[dark, ar]
        pick = np.where(is_shadow, dark, pick)
    vflat = valid.reshape(4, -1)
    vflat[pick, cols] = False
    if prefer is not None:
        pf = np.asarray(prefer, dtype=bool).reshape(4, -1)[:, cols]
        use = ~is_shadow & pf.any(axis=0)
        if use.any():
            vflat[:, cols[use]] = ~pf[:, use]
    return valid


def apply(images, ctx):
    """Image stage: NL, or NL-Re when Re is in the expression."""
    t, rg = ctx.thresholds, ctx.ranges
    prefer = None
    if "Re" in ctx.tokens:
        n0, _ = kernel.split(kernel.ls(images, ctx.S))
        prefer = ~reflection_valid(n0, ctx.directions, ctx.t_re())
    return nl(images, ctx.S, t["t_NL"], scale=ctx.scale,
              shadow_level=rg["lo"] + np.float32(t["k_low"]) * rg["rng"], prefer=prefer)


MASK = Mask("NL", "image", apply, images=(4, 4), thresholds=(T_NL, K_LOW, T_RE), ranges=True,
            help="non-Lambert quadruple of four images (Eqs. 3.3-3.6); xNL for other counts")
