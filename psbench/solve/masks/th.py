"""Th: the threshold mask (Eq. 3.2).

**Th offset.** The thesis writes ``i < k_low (i_max - i_min)`` and
``i > k_up (i_max - i_min)``: the bounds are fractions of the range, not offset by
i_min. psbench keeps that literal rule by default (``th_offset=False``);
``th_offset=True`` offsets both bounds by i_min (``i < i_min + k_low (i_max -
i_min)``), which is invariant to an added constant (ambient light, dark level).
Noiseless renders have i_min = 0 and both give the same masks; with noise the
image minimum is a negative noise extreme (about -4 sigma), which drags both
offset bounds down: shadows escape the lower bound and lit diffuse observations
exceed the upper one. On the five test surfaces (45x8, TS, 256 px) Th's mean NE
with offset / literal / None: 5 % noise 18.1 / 10.1 / 10.1 deg, 10 % noise
28.2 / 17.3 / 11.9 deg, 20 % noise 36.3 / 19.7 / 16.4 deg.

The ranges come from ``th_scope`` (:mod:`psbench.solve.masks._ranges`); images with
zero range are never masked.
"""
from __future__ import annotations

import numpy as np

from ...registry import Mask, Threshold
from ..thresholds import COUNTS, TABLE_5_2
from ._shared import K_LOW

__all__ = ["th", "keep_at_least", "apply", "MASK"]

K_UP = Threshold("k_up", TABLE_5_2["k_up"], (0.0, 1.0), counts=COUNTS,
                 help="Th upper bound, fraction of the dynamic range (Eq. 3.2, Table 5.2)")
TH_KEEP = Threshold("th_keep", 0.0, (0.0, 0.99),
                    help="Th keeps at least this fraction of each pixel's observations, the "
                         "least out of bounds first (0: literal Eq. 3.2)")


def th(images, lo, rng, k_low, k_up, *, lo_up=None, rng_up=None, out=None):
    """Threshold mask (Eq. 3.2): valid where lo + k_low rng <= i <= lo_up + k_up rng_up.

    Parameters
    ----------
    images : (k, *P) float32
    lo, rng : arrays broadcastable to images
        Offset and range of the lower bound (and of the upper bound unless ``lo_up``,
        ``rng_up`` are given).

    Returns
    -------
    valid : (k, *P) bool
    """
    lo_up = lo if lo_up is None else lo_up
    rng_up = rng if rng_up is None else rng_up
    low = (lo + np.float32(k_low) * rng).astype(np.float32)
    up = (lo_up + np.float32(k_up) * rng_up).astype(np.float32)
    valid = np.greater_equal(images, low, out=out)
    valid &= images <= up
    return valid


def keep_at_least(images, valid, low, up, scale, fraction):
    """Give back, where a pixel keeps fewer than ``q = max(3, ceil(fraction * k))``
    observations (at most k), the masked ones closest to the bounds until q are kept.

    The distance of a masked observation to the valid interval is measured in units of
    ``scale`` (its image's range): ``max(low - i, i - up) / scale``. In place on
    ``valid`` (k, *P); returns it.
    """
    k = images.shape[0]
    q = min(k, max(3, int(np.ceil(fraction * k - 1e-9))))
    flat_v = valid.reshape(k, -1)
    short = np.flatnonzero(np.count_nonzero(flat_v, axis=0) < q)
    if short.size == 0:
        return valid
    i = images.reshape(k, -1)[:, short]
    lo = np.broadcast_to(low, images.shape).reshape(k, -1)[:, short]
    hi = np.broadcast_to(up, images.shape).reshape(k, -1)[:, short]
    sc = np.broadcast_to(scale, images.shape).reshape(k, -1)[:, short]
    dist = np.maximum(lo - i, i - hi) / np.maximum(sc, np.float32(1e-30))
    dist[flat_v[:, short]] = -np.inf                       # kept ones first
    order = np.argsort(dist, axis=0, kind="stable")[:q]
    sub = flat_v[:, short]
    np.put_along_axis(sub, order, True, axis=0)
    flat_v[:, short] = sub
    return valid


def apply(images, ctx):
    """Image stage: Eq. 3.2 with the ranges of ``ctx`` (and ``th_keep``)."""
    rg, t = ctx.ranges, ctx.thresholds
    valid = th(images, rg["lo"], rg["rng"], t["k_low"], t["k_up"], lo_up=rg["lo_up"],
               rng_up=rg["rng_up"])
    if rg["dead"].any():
        valid |= rg["dead"]
    keep = t.get("th_keep", 0.0)
    if keep:
        low = rg["lo"] + np.float32(t["k_low"]) * rg["rng"]
        up = rg["lo_up"] + np.float32(t["k_up"]) * rg["rng_up"]
        keep_at_least(images, valid, low, up, rg["rng_up"], keep)
    return valid


MASK = Mask("Th", "image", apply, thresholds=(K_LOW, K_UP, TH_KEEP), ranges=True,
            help="shadows below k_low and highlights above k_up of each image's range (Eq. 3.2)")
