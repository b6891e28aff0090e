"""Neighbour propagation of tsfit: pixels restart from their neighbours' normals.

The per-pixel cost is not convex (the highlight lobe and the self-shadow
terminator each create basins), so a pixel can end in a local minimum whose normal
disagrees with the pixels around it while a neighbour's solution lies in a lower
basin of its own cost. Surfaces are mostly smooth at the pixel scale, so a
neighbour's normal is a good start in the right basin: this is the propagation
step of PatchMatch-style per-pixel solvers. Nothing is smoothed: a pixel takes the
refit only if it lowers *its own* cost, so where the surface has a crease the
pixel keeps its solution.

Which pixels are retried: those whose normal differs from the mean normal of their
8 neighbours by more than ``FLAG`` times the median of that difference over the
object (a scale-free rule: the median reflects the noise and the curvature of the
object at hand). Each retried pixel restarts Levenberg–Marquardt from that mean
normal (rho_d, and rho_s when per pixel, in closed form) and keeps the result if
it lowers its cost by more than the fit's tolerance (``GAIN``). Sweeps repeat on
the disagreeing pixels next to a change, so a correct solution spreads into a
cluster of wrong ones. (Restarting from the best of the 8 neighbours' own normals
instead was measured as no more accurate and slower.)
"""
from __future__ import annotations

import numpy as np

from . import _lm
from . import _aux_kernel as _kx
from ._start import take

__all__ = ["Grid", "propagate"]

#: retry threshold: multiples of the median angle between a normal and its
#: neighbours' mean normal
FLAG = 3.0
#: sweeps at most (a change spreads by one pixel per sweep)
SWEEPS = 2
#: a refit replaces a pixel's solution when it lowers the cost by this fraction
#: (smaller differences are Levenberg–Marquardt's tolerance, not another basin)
GAIN = 1e-3


class Grid:
    """The gathered object pixels on the image grid (8-neighbourhoods).

    Parameters
    ----------
    idx : (P,) int
        Flat indices of the gathered pixels in the (H, W) image.
    shape : (H, W)
    fitted : (P,) bool
        Pixels that take part (the others are never a neighbour).
    """

    def __init__(self, idx, shape, fitted):
        H, W = shape
        self.shape = shape
        self.idx = idx
        self.fitted = np.ascontiguousarray(fitted, dtype=bool)
        y, x = np.divmod(idx, W)
        self.flat = (y + 1) * (W + 2) + (x + 1)  # in the 1-pixel padded grid
        self.pos = np.full((H + 2) * (W + 2), -1, dtype=np.int64)  # padded grid -> pixel
        f = np.flatnonzero(self.fitted)
        self.pos[self.flat[f]] = f

    def near(self, changed):
        """(P,) bool: fitted pixels with a changed pixel among their 8 neighbours."""
        out = np.empty(self.idx.size, dtype=bool)
        _kx.near(self.pos, self.flat, self.shape[1] + 2, np.ascontiguousarray(changed),
                 self.fitted, out)
        return out

    def disagreement(self, n):
        """Angle (radians) between each fitted normal and the mean of its fitted
        neighbours' normals (NaN where there is none), and that mean (3, P)."""
        P = self.idx.size
        mean = np.empty((3, P), dtype=np.float32)
        ang = np.empty(P, dtype=np.float32)
        _kx.neighbour_mean(self.pos, self.flat, self.shape[1] + 2,
                           np.ascontiguousarray(n, dtype=np.float32), self.fitted, mean, ang)
        return ang, mean


def propagate(L, I, w, n, rd, rs, m, rs_max, cost, grid, cols, opt, iters, conv, rs_fixed,
              *, sweeps=SWEEPS):
    """Retry disagreeing pixels from their neighbours' mean normal (in place).

    Parameters
    ----------
    L : _lm.Lights
    I, w : (k, P) float32
    n : (3, P) float32; rd, rs, m, rs_max : (P,) float32; cost : (P,) float64
        The fitted state, updated in place where a retry lowers the cost.
    grid : Grid
    cols : tuple
        Per-pixel unknowns besides n and rho_d (as for :func:`_lm.fit`).
    opt : TsfitOptions
    iters : (P,) int32, conv : (P,) bool
        Updated in place.
    rs_fixed : bool
        rho_s is shared (not re-solved per pixel).
    sweeps : int
        Sweeps at most.

    Returns
    -------
    int
        Pixels whose solution changed.
    """
    P = n.shape[1]
    changed = np.zeros(P, dtype=bool)
    d, mean = grid.disagreement(n)
    ok = np.isfinite(d)
    if not ok.any():
        return 0
    thresh = FLAG * float(np.median(d[ok]))
    todo = ok & (d > thresh)
    for _ in range(sweeps):
        sel = np.flatnonzero(todo)
        if sel.size == 0:
            break
        Is, ws, rsm = take(I, sel), take(w, sel), rs_max[sel]
        ms = m[sel].copy()
        ns = take(mean, sel)
        rds, rss = _lm.init_rho(L, Is, ws, ns, ms, rsm, rs=rs[sel] if rs_fixed else None)
        it, cv, c = _lm.fit(L, Is, ws, ns, rds, rss, ms, rsm, cols=cols, m_lo=opt.m_min,
                            m_hi=opt.m_max, max_iter=opt.lm_max_iter, tol=opt.lm_tol)
        iters[sel] += it
        win = c < cost[sel] * (1 - GAIN)
        pick = sel[win]
        if pick.size == 0:
            break
        n[:, pick], rd[pick], rs[pick], m[pick] = ns[:, win], rds[win], rss[win], ms[win]
        cost[pick], conv[pick] = c[win], cv[win]
        changed[pick] = True
        # next sweep: the disagreeing neighbours of a change (their mean moved)
        new = np.zeros(P, dtype=bool)
        new[pick] = True
        near = grid.near(new)
        d, mean = grid.disagreement(n)
        todo = near & np.isfinite(d) & (d > thresh)
    return int(changed.sum())
