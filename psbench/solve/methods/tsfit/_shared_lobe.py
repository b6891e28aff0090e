"""The specular lobe shared by the whole object: rho_s and/or m estimated on a sample.

Variable projection: for given shared values every pixel is fitted on its own; the
shared values then take Gauss–Newton steps on the total cost with the per-pixel
unknowns projected out (:func:`psbench.solve.methods.tsfit._lm.reduced`), each step
followed by a warm-started refit of the sample and accepted only if the total
cost drops.
"""
from __future__ import annotations

import numpy as np

from . import _lm, _grid as _tsgrid
from ._start import take

__all__ = ["estimate"]

#: pixels of the sub-sample that picks the coarse m, and LM iterations there
COARSE, COARSE_ITER = 500, 8
#: coarse m values, log-spaced over [m_min, m_max]
M_GRID = 8
#: Gauss–Newton steps on the shared unknowns: at most this many, until a step moves
#: them by less than TOL (relative)
MAX_STEPS, TOL = 20, 1e-3


def _fit(L, I, w, n, rs_max, m_val, rs_val, cols, opt, *, grid=True, max_iter=None):
    """Fit the sample at the given lobe (rs_val None: per pixel); returns the state
    (n, rd, rs, m) and the per-pixel cost."""
    P = n.shape[1]
    m = np.full(P, m_val, dtype=np.float32)
    rs_fixed = None if rs_val is None else np.full(P, rs_val, dtype=np.float32)
    if grid and opt.start_grid:
        n = _tsgrid.grid_start(L, I, w, n, m_val, opt.start_grid, rs=rs_fixed)[0]
    else:
        n = n.copy()
    rd, rs = _lm.init_rho(L, I, w, n, m, rs_max, rs=rs_fixed)
    _, _, c = _lm.fit(L, I, w, n, rd, rs, m, rs_max, cols=cols, m_lo=opt.m_min,
                      m_hi=opt.m_max, max_iter=max_iter or opt.lm_max_iter, tol=opt.lm_tol)
    return (n, rd, rs, m), c


def _coarse_m(L, I, w, n0, rs_max, opt):
    """The m of a log grid that explains the sample best: per-pixel fits (rho_s per
    pixel, from the grid start) at each m, compared by their total cost."""
    grid = np.geomspace(opt.m_min, opt.m_max, M_GRID)
    costs = [_fit(L, I, w, n0, rs_max, g, None, ("rs",), opt, max_iter=COARSE_ITER)[1].sum()
             for g in grid]
    return float(grid[int(np.argmin(costs))])


def estimate(L, I, w, n0, rs_max, opt, seed, cand):
    """Shared lobe values on a random sample of the pixels ``cand``.

    Returns
    -------
    rs : float or None
        Shared rho_s (None when ``opt.rho_s_mode == "pixel"``).
    m : float
        Shared m (the start of a per-pixel m; ``m_init`` when fixed).
    """
    share_rs = opt.rho_s_mode == "shared"
    share_m = opt.m_mode != "fixed"  # a per-pixel m starts from the shared estimate
    m0 = float(opt.m_init) if opt.m_init is not None else float(np.sqrt(opt.m_min * opt.m_max))
    if cand.size == 0:
        return (0.0 if share_rs else None), m0
    rng = np.random.default_rng(seed)
    sel = np.sort(rng.choice(cand, size=min(opt.m_sample, cand.size), replace=False))
    Is, ws, ns, rsm = take(I, sel), take(w, sel), take(n0, sel), rs_max[sel]
    if opt.m_init is None and opt.m_mode != "fixed":
        sub = slice(0, None, max(1, sel.size // COARSE))
        m0 = _coarse_m(L, Is[:, sub], ws[:, sub], ns[:, sub], rsm[sub], opt)
    if not share_rs and not share_m:
        return None, m0
    rs0 = None
    if share_rs:  # start: per-pixel rho_s where the lobe's peak region is sampled
        (n, rd, rs, m), _ = _fit(L, Is, ws, ns, rsm, m0, None, ("rs",), opt)
        th = np.arccos(np.clip(L.h @ n, -1, 1))
        seen = ((np.exp(-np.square(m0 * th)) > 0.5) & (ws > 0)).any(axis=0)
        rs0 = float(np.median(rs[seen] if seen.any() else rs))
        ns = n
    cols = () if share_rs else ("rs",)
    glob = (("rs",) if share_rs else ()) + (("m",) if share_m else ())
    state, c = _fit(L, Is, ws, ns, rsm, m0, rs0, cols, opt)
    total = float(c.sum())
    vals = {"rs": rs0, "m": m0}
    rs_cap = float(np.median(rsm))
    for _ in range(MAX_STEPS):
        step = _lm.reduced(L, Is, ws, *state, cols, glob)
        accepted = False
        for _ in range(6):
            new = dict(vals)
            for name, s in zip(glob, step):
                v = vals[name]
                if name == "m":
                    new["m"] = float(np.clip(v + np.clip(s, -0.5 * v, v), opt.m_min, opt.m_max))
                else:
                    new["rs"] = float(np.clip(v + np.clip(s, -0.5 * max(v, 1e-12), max(v, rs_cap)),
                                              0.0, rs_cap))
            moved = max(abs(new[nm] - vals[nm]) / max(abs(vals[nm]), 1e-12) for nm in glob)
            if moved <= TOL / 10:
                break
            n, rd, rs, m = (a.copy() for a in state)
            m[:] = new["m"]
            if share_rs:
                rs[:] = new["rs"]
            _, _, c = _lm.fit(L, Is, ws, n, rd, rs, m, rsm, cols=cols, m_lo=opt.m_min,
                              m_hi=opt.m_max, max_iter=opt.lm_max_iter, tol=opt.lm_tol)
            if c.sum() < total:
                state, total, vals, accepted = (n, rd, rs, m), float(c.sum()), new, True
                break
            step = step * 0.25
        if not accepted or moved <= TOL:
            break
    return vals["rs"], vals["m"]
