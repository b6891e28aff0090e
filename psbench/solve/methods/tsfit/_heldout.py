"""tsfit's held-out validation: the fitted model's held-out errors and validation error
per pixel (:mod:`psbench.solve.validation`), at every pixel or, for ``robust``, at the
pixels it asks for, and the held-out fallback to the start
(:mod:`psbench.solve.fallback`)."""
from __future__ import annotations

import numpy as np

from ._start import take

__all__ = ["heldout", "lazy_heldout", "fall_back"]


def heldout(L, I, w, n, rd, rs, m):
    """The fitted model's held-out errors (k, P) float32 over the observations of
    positive weight and its per-pixel validation error (P,) float32
    (:mod:`psbench.solve.validation`)."""
    from ...validation import ts_heldout, validation_map
    P = I.shape[1]
    e = np.empty(I.shape, dtype=np.float32)
    vals = np.empty(P, dtype=np.float32)
    for lo in range(0, P, 1 << 16):
        s = slice(lo, lo + (1 << 16))
        e[:, s], med = ts_heldout(I[:, s], L.table, w[:, s], n[:, s], rd[s], rs[s], m[s],
                                  median=True)
        vals[s] = validation_map(None, w[:, s], I[:, s], median=med)
    return e, vals


def lazy_heldout(L, I, w, n, rd, rs, m):
    """:func:`heldout` at chosen pixels, as a function of their indices (see
    :func:`~.method.tsfit_lazy_heldout`). Each pixel's errors are its own; the validation
    error's intensity floor is that of the pixel's block of :func:`heldout` (a mean
    over the block), so it is computed from every pixel, as there."""
    from ...validation import intensity_floor, ts_heldout, validation_map

    def at(sel):
        sel = np.asarray(sel, dtype=np.intp)
        Is, ws = take(I, sel), take(w, sel)
        e, med = ts_heldout(Is, L.table, ws, take(n, sel), rd[sel], rs[sel], m[sel],
                            median=True)
        floor = np.empty(sel.size)
        for lo in range(0, I.shape[1], 1 << 16):
            s = slice(lo, lo + (1 << 16))
            sl = (sel >= lo) & (sel < lo + (1 << 16))
            if sl.any():
                floor[sl] = intensity_floor(I[:, s])
        return e, ws, validation_map(None, ws, Is, median=med, floor=floor)
    return at


def fall_back(I, w, e_fit, vals, start, sigma, kept, scale):
    """The held-out fallback (:mod:`psbench.solve.fallback`): (P,) bool, the pixels
    that keep the start (its held-out errors, used observations and validation error
    or None, ``start``): those
    where the fit does not predict better, and those never fitted (``kept``); and the
    margin (P,) float32 (:func:`psbench.solve.fallback.margin`). Updates
    ``w``, ``e_fit`` and ``vals`` there to the start's, in place."""
    from ... import fallback as _fb
    from ...validation import validation_map
    e0, u0, ve0 = start
    mean, se, cnt = _fb.compare(e_fit, e0, w | u0, sigma, scale=scale)
    t = _fb.margin(mean, se, cnt)
    t[kept] = -np.inf
    fell = ~(t > _fb.Z)
    j = np.flatnonzero(fell)
    if j.size:
        w[:, j] = u0[:, j]
        e_fit[:, j] = e0[:, j]
        vals[j] = (validation_map(e0[:, j], u0[:, j], I[:, j]) if ve0 is None
                   else ve0[j])   # the start's own, when it reports it
    return fell, t.astype(np.float32)
