"""Levenberg–Marquardt for the per-pixel Lambert + Torrance–Sparrow model.

The model of observation i at one pixel (distant light direction d_i, power mu_i,
orthographic view v = (0, 0, 1), bisector h_i = (d_i + v) / |d_i + v|):

    f_i = mu_i [rho_d (d_i . n) + rho_s exp(-m^2 theta_i^2)]   if d_i . n > 0, else 0,
    theta_i = arccos(h_i . n).

Unknowns per pixel: the unit normal n (two tangent-plane angles), rho_d and,
optionally, rho_s and m. Every pixel's problem is independent: the compiled kernels
of :mod:`psbench.solve.methods.tsfit._kernel` fit each pixel in registers, in
parallel over pixels. The n-gradient of f_i is mu_i (rho_d d_i + kappa B_i h_i) with
kappa = 2 m^2 rho_s and B_i = E_i theta_i / sin(theta_i), E_i = exp(-m^2 theta_i^2).

Layout: pixels last. Observations are (k, p) float32, weights (k, p) float32 or
bool, normals (3, p) float32, per-pixel values (p,) float32.
"""
from __future__ import annotations

import numpy as np

from . import _kernel as _kr

__all__ = ["Lights", "evaluate", "fit", "init_rho", "reduced", "predict"]

#: pixels per block of :func:`reduced` (bounds its (q, q, p) temporaries)
BLOCK = 4096


class Lights:
    """Per-light constants of the model (distant lights, orthographic view)."""

    def __init__(self, directions, power):
        d = np.asarray(directions, dtype=np.float64)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        h = d + np.array([0.0, 0.0, 1.0])
        h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
        mu = np.asarray(power, dtype=np.float64).reshape(-1)
        self.k = d.shape[0]
        f32 = np.float32
        self.d, self.h = d.astype(f32), h.astype(f32)  # (k, 3)
        self.mu = mu.astype(f32)
        self.table = _kr.tables(self.d, self.h, self.mu)  # the kernels' (7, k) table


def _flags(cols):
    """(fit_rs, fit_m) of the per-pixel unknowns ``cols`` (rs before m)."""
    cols = tuple(cols)
    if cols not in ((), ("rs",), ("m",), ("rs", "m")):
        raise ValueError(f"cols must be a subset of ('rs', 'm') in that order, got {cols}")
    return int("rs" in cols), int("m" in cols)


def _f32(a):
    return np.ascontiguousarray(a, dtype=np.float32)


def _obs(I, w):
    """Observations and weights as the kernels take them: C-contiguous float32, bool
    weights viewed as uint8 (one compiled specialisation per weight type)."""
    I = np.ascontiguousarray(I, dtype=np.float32)
    w = np.ascontiguousarray(w)
    return I, (w.view(np.uint8) if w.dtype == bool else w.astype(np.float32, copy=False))


def predict(L, n, rd, rs, m):
    """Model images f (k, p) float32 for normals n (3, p) and per-pixel rd, rs, m."""
    out = np.empty((L.k, n.shape[1]), dtype=np.float32)
    _kr.predict(L.table, _f32(n), _f32(rd), _f32(rs), _f32(m), out)
    return out


def evaluate(L, I, w, n, rd, rs, m, *, jac=False, cols=()):
    """Weighted cost and (optionally) normal equations at the given parameters.

    Parameters
    ----------
    L : Lights
    I : (k, p) float32
    w : (k, p) float32 or bool
        Observations and weights.
    n : (3, p) float32 unit normals; rd, rs, m : (p,) float32.
    jac : bool
        Also return the normal matrix A (q, q, p) float64 and g = J^T W r (q, p)
        float64 in the coordinates (t1 angle, t2 angle, rho_d, *cols), and the
        tangent basis (t1, t2) (3, p) float32 used.
    cols : tuple of {"rs", "m"}
        Per-pixel unknowns after (angle, angle, rho_d), in this order.

    Returns
    -------
    cost : (p,) float64 = sum_i w_i (I_i - f_i)^2; with ``jac`` also (A, g, t1, t2).
    """
    fit_rs, fit_m = _flags(cols)
    p = n.shape[1]
    cost = np.empty(p)
    S = np.empty((p if jac else 1, _kr.NSUM))
    t = np.empty((p if jac else 1, 2, 3))
    _kr.evaluate(L.table, *_obs(I, w), _f32(n), _f32(rd), _f32(rs), _f32(m), jac, cost, S, t)
    if not jac:
        return cost
    ix = [0, 1, 2] + [3] * fit_rs + [4] * fit_m
    tri = lambda a, b: max(a, b) * (max(a, b) + 1) // 2 + min(a, b)  # noqa: E731
    A = np.stack([np.stack([S[:, tri(a, b)] for b in ix]) for a in ix])
    g = np.ascontiguousarray(S[:, [15 + a for a in ix]].T)
    t = np.ascontiguousarray(t.transpose(1, 2, 0), dtype=np.float32)
    return cost, A, g, t[0], t[1]


def fit(L, I, w, n, rd, rs, m, rs_max, *, cols=(), m_lo=1.0, m_hi=50.0, max_iter=100,
        tol=1e-5):
    """Levenberg–Marquardt on every pixel (in place on n, rd, rs, m).

    Per pixel (compiled; in parallel over pixels, no reduction across them): Marquardt
    damping scaled by the diagonal of J^T W J (floored for unknowns carrying no
    information, e.g. m where rho_s = 0), an active set for unknowns at their bounds
    (a step pointing outwards is held), a Cholesky solve, the step accepted if the
    cost drops (damping / 5) else rejected (damping x 8). The normal moves on the
    sphere, n <- normalize(n + a t1 + b t2) with (t1, t2) a tangent basis at n, so it
    stays unit without a pole singularity. A pixel stops when a step is below
    ``tol`` in every unknown (radians for n, relative to the pixel's albedo for
    rho_d and rho_s, relative to m for m); that last step is taken without
    evaluating it (the Gauss-Newton model is exact to second order there).

    Parameters
    ----------
    L : Lights
    I : (k, P) float32
    w : (k, P) float32 or bool
    n : (3, P) float32 unit; rd, rs, m, rs_max : (P,) float32
        Start values (overwritten) and the per-pixel upper bound on rho_s.
    cols : tuple of {"rs", "m"}
        Per-pixel unknowns besides n and rho_d; the others stay as given.

    Returns
    -------
    iterations : (P,) int32, converged : (P,) bool, cost : (P,) float64
        ``cost`` is that of the last evaluated state.
    """
    fit_rs, fit_m = _flags(cols)
    P = I.shape[1]
    iters = np.zeros(P, dtype=np.int32)
    conv = np.zeros(P, dtype=bool)
    cost = np.zeros(P)
    state = [a if (a.dtype == np.float32 and a.flags.c_contiguous) else _f32(a)
             for a in (n, rd, rs, m)]
    _kr.lm_fit(L.table, *_obs(I, w), *state, _f32(rs_max), fit_rs, fit_m, float(m_lo),
               float(m_hi), int(max_iter), float(tol), iters, conv, cost)
    for dst, src in zip((n, rd, rs, m), state):
        if src is not dst:
            dst[...] = src
    return iters, conv, cost


def init_rho(L, I, w, n, m, rs_max, rs=None, *, cost=False):
    """Least-squares (rho_d, rho_s) for fixed n and m (2x2 per pixel, clipped to the
    bounds): a start that already accounts for the highlight. With ``rs`` given
    (p,), only rho_d is solved. Returns float32 (rd, rs), (p,) each; with ``cost``
    also the cost at that (n, rd, rs, m) (float64, from the same sums)."""
    P = n.shape[1]
    rd_out = np.empty(P, dtype=np.float32)
    rs_out = np.empty(P, dtype=np.float32)
    c = np.empty(P if cost else 1)
    has_rs = rs is not None
    _kr.init_rho(L.table, *_obs(I, w), _f32(n), _f32(m), _f32(rs_max),
                 _f32(rs) if has_rs else rd_out, has_rs, bool(cost), rd_out, rs_out, c)
    return (rd_out, rs_out, c) if cost else (rd_out, rs_out)


def _solve_spd(A, g):
    """Solve the batched SPD systems A x = g, A (q, q, p) (overwritten), g (q, p).

    Returns x (q, p) and a (p,) bool flag of the systems that were positive definite.
    """
    q, _, p = A.shape
    ok = np.ones(p, dtype=bool)
    Lm = A
    for j in range(q):
        d = Lm[j, j] - sum(Lm[j, t] * Lm[j, t] for t in range(j)) if j else Lm[j, j].copy()
        ok &= d > 0
        d = np.sqrt(np.where(d > 0, d, 1.0))
        Lm[j, j] = d
        for i in range(j + 1, q):
            acc = Lm[i, j] - sum(Lm[i, t] * Lm[j, t] for t in range(j)) if j else Lm[i, j]
            Lm[i, j] = acc / d
    y = np.empty_like(g)
    for i in range(q):  # forward: L y = g
        y[i] = (g[i] - sum(Lm[i, t] * y[t] for t in range(i))) / Lm[i, i]
    x = np.empty_like(g)
    for i in reversed(range(q)):  # back: L^T x = y
        x[i] = (y[i] - sum(Lm[t, i] * x[t] for t in range(i + 1, q))) / Lm[i, i]
    return x, ok



def reduced(L, I, w, n, rd, rs, m, cols, glob):
    """Gauss–Newton step for unknowns shared by all pixels, the per-pixel ones
    projected out.

    At per-pixel optima (gradient ~ 0 in the pixel's own unknowns), the reduced
    curvature of the total cost in the shared unknowns ``glob`` is
    sum_p (A_gg - A_gx A_xx^-1 A_xg) and the reduced gradient
    sum_p (g_g - A_gx A_xx^-1 g_x) (Schur complement). Returns the step
    (len(glob),) solving that system (zeros if it is singular).
    """
    k, P = I.shape
    block = BLOCK
    qx = 3 + len(cols)
    ng = len(glob)
    Hs = np.zeros((ng, ng))
    gs = np.zeros(ng)
    for lo in range(0, P, block):
        s = slice(lo, min(P, lo + block))
        _, A, g, _, _ = evaluate(L, I[:, s], w[:, s], n[:, s], rd[s], rs[s], m[s], jac=True,
                                 cols=tuple(cols) + tuple(glob))
        Axx = A[:qx, :qx]
        ridge = 1e-9 * sum(Axx[i, i] for i in range(qx)) + 1e-30
        for i in range(qx):
            Axx[i, i] += ridge
        Axg = A[:qx, qx:]
        sol = []
        for j in range(ng):
            u, ok = _solve_spd(Axx.copy(), Axg[:, j].copy())
            sol.append(np.where(ok, u, 0.0))
        v, ok = _solve_spd(Axx.copy(), g[:qx].copy())
        v = np.where(ok, v, 0.0)
        Hp = A[qx:, qx:] - np.einsum("igp,ihp->ghp", Axg, np.stack(sol, axis=1))
        gp = g[qx:] - np.einsum("igp,ip->gp", Axg, v)
        fin = np.isfinite(Hp).all((0, 1)) & np.isfinite(gp).all(0)
        Hs += Hp[..., fin].sum(-1)
        gs += gp[:, fin].sum(-1)
    try:
        step = np.linalg.solve(Hs + (1e-9 * np.trace(Hs) + 1e-300) * np.eye(ng), gs)
    except np.linalg.LinAlgError:
        return np.zeros(ng)
    return step if np.isfinite(step).all() else np.zeros(ng)
