"""Batched Levenberg–Marquardt for the per-pixel Lambert + Torrance–Sparrow model.

The model of observation i at one pixel (distant light direction d_i, power mu_i,
orthographic view v = (0, 0, 1), bisector h_i = (d_i + v) / |d_i + v|):

    f_i = mu_i [rho_d (d_i . n) + rho_s exp(-m^2 theta_i^2)]   if d_i . n > 0, else 0,
    theta_i = arccos(h_i . n).

Unknowns per pixel: the unit normal n (two tangent-plane angles), rho_d, rho_s and,
optionally, m. Every pixel's problem is independent; all are solved at once. Pixels
are processed in blocks that fit in cache; within a block every LM iteration works
on the still unconverged pixels only.

Normal equations without forming the (p, k, q) Jacobian: the n-gradient of f_i is
a_i d_i + b_i h_i, so every n-block of J^T W J is a product of a (p, k) coefficient
array with a per-light constant table ((k, 6) for d d^T, (k, 3) for d, ...), i.e. a
matrix product. Residuals and Jacobian coefficients are float32; the small (q, q)
systems are solved in float64.
"""
from __future__ import annotations

import numpy as np

__all__ = ["Lights", "evaluate", "fit", "init_rho", "reduced", "grid_start", "hemisphere"]

#: (p * k) float32 elements per block: a few MB of working set, cache-friendly
BLOCK_ELEMS = 1 << 17
_IU = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))
_SYM = np.array([[0, 1, 2], [1, 3, 4], [2, 4, 5]])  # 6 unique entries -> 3x3


class Lights:
    """Per-light constants of the model (distant lights, orthographic view)."""

    def __init__(self, directions, power):
        d = np.asarray(directions, dtype=np.float64)
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        h = d + np.array([0.0, 0.0, 1.0])
        h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
        self.k = d.shape[0]
        self.d, self.h = d.astype(np.float32), h.astype(np.float32)
        self.Dt, self.Ht = np.ascontiguousarray(self.d.T), np.ascontiguousarray(self.h.T)
        self.mu = np.asarray(power, dtype=np.float32).reshape(-1)
        dd = d[:, :, None] * d[:, None, :]
        hh = h[:, :, None] * h[:, None, :]
        dh = d[:, :, None] * h[:, None, :]
        f32 = np.float32
        self.DD = dd[:, _IU[0], _IU[1]].astype(f32)
        self.HH = hh[:, _IU[0], _IU[1]].astype(f32)
        self.DH = (dh + dh.transpose(0, 2, 1))[:, _IU[0], _IU[1]].astype(f32)


def _tangents(n):
    """Orthonormal tangent basis (t1, t2) of unit normals n (p, 3)."""
    # cross with the coordinate axis least aligned with n: never degenerate
    ax = np.where((np.abs(n[:, 0]) < 0.6)[:, None], np.float32([1, 0, 0]), np.float32([0, 1, 0]))
    t1 = np.cross(ax, n)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(n, t1)
    return t1, t2


def evaluate(L, I, w, n, rd, rs, m, *, jac=False, cols=("rs",)):
    """Weighted cost and (optionally) normal equations at the given parameters.

    Parameters
    ----------
    L : Lights
    I, w : (p, k) float32
        Observations and weights.
    n : (p, 3) float32 unit normals; rd, rs, m : (p,) float32.
    jac : bool
        Also return the normal matrix A (p, q, q) float64 and the gradient
        g = J^T W r (p, q) float64 in the coordinates (t1 angle, t2 angle, rho_d,
        *cols), plus the tangent basis used.
    cols : tuple of {"rs", "m"}
        Unknowns after (angle, angle, rho_d), in this order.

    Returns
    -------
    cost : (p,) float64 = sum_i w_i (I_i - f_i)^2, and with ``jac`` also (A, g, t1, t2).
    """
    c = n @ L.Dt
    ch = n @ L.Ht
    np.clip(ch, -1.0, 1.0, out=ch)
    th = np.arccos(ch)
    E = th * m[:, None]
    np.square(E, out=E)
    np.negative(E, out=E)
    np.exp(E, out=E)
    G = (c > 0) * L.mu  # d f / d(bracket), 0 in self shadow
    f = rd[:, None] * c
    f += rs[:, None] * E
    f *= G
    r = np.subtract(I, f, out=f)
    wr = w * r
    cost = np.einsum("pk,pk->p", wr, r, dtype=np.float64)
    if not jac:
        return cost
    q = 3 + len(cols)
    p = n.shape[0]
    # d f / d n = a d + b h ;  b = G rs E 2 m^2 theta / sin(theta)
    s2 = 1.0 - ch * ch
    np.maximum(s2, 0.0, out=s2)
    sin = np.sqrt(s2, out=s2)
    ratio = np.divide(th, sin, out=np.ones_like(th), where=sin > 1e-6)
    a = G * rd[:, None]
    GE = G * E  # d f / d rho_s
    b = GE * (rs * 2.0 * m * m)[:, None]
    b *= ratio
    J = [G * c]  # d f / d rho_d
    for name in cols:
        if name == "rs":
            J.append(GE)
        else:  # d f / d m = -2 m theta^2 rs G E
            dm = GE * th
            dm *= th
            dm *= (-2.0 * m * rs)[:, None]
            J.append(dm)
    wa, wb = w * a, w * b
    M = (wa * a) @ L.DD
    M += (wa * b) @ L.DH
    M += (wb * b) @ L.HH  # (p, 6): sum w (a d + b h)(a d + b h)^T
    # n-cross terms with the scalar unknowns and the n-gradient: (a d + b h) . x
    V = np.stack([wr * a] + [wa * col for col in J]) @ L.d
    V += np.stack([wr * b] + [wb * col for col in J]) @ L.h  # (q - 1, p, 3)
    t1, t2 = _tangents(n)
    A = np.empty((p, q, q), dtype=np.float64)
    g = np.empty((p, q), dtype=np.float64)
    Ms = M[:, _SYM]  # (p, 3, 3)
    T = (t1, t2)
    MT = [np.einsum("pij,pj->pi", Ms, t) for t in T]
    for i in range(2):
        for j in range(i, 2):
            A[:, i, j] = A[:, j, i] = np.einsum("pi,pi->p", T[i], MT[j])
        g[:, i] = np.einsum("pi,pi->p", T[i], V[0])
        for j, v in enumerate(V[1:]):
            A[:, i, 2 + j] = A[:, 2 + j, i] = np.einsum("pi,pi->p", T[i], v)
    for i, ci in enumerate(J):
        wci = w * ci
        g[:, 2 + i] = np.einsum("pk,pk->p", wci, r)
        for j in range(i, len(J)):
            A[:, 2 + i, 2 + j] = A[:, 2 + j, 2 + i] = np.einsum("pk,pk->p", wci, J[j])
    return cost, A, g, t1, t2


def _solve_spd(A, g):
    """Solve the batched SPD systems A x = g (p, q, q) by Cholesky (in place on A).

    Returns x (p, q) and a (p,) bool flag of systems that were positive definite.
    """
    p, q, _ = A.shape
    ok = np.ones(p, dtype=bool)
    Lm = A
    for j in range(q):
        d = Lm[:, j, j] - np.einsum("pk,pk->p", Lm[:, j, :j], Lm[:, j, :j])
        ok &= d > 0
        d = np.sqrt(np.where(d > 0, d, 1.0))
        Lm[:, j, j] = d
        for i in range(j + 1, q):
            Lm[:, i, j] = (Lm[:, i, j] - np.einsum("pk,pk->p", Lm[:, i, :j], Lm[:, j, :j])) / d
    y = np.empty_like(g)
    for i in range(q):  # forward: L y = g
        y[:, i] = (g[:, i] - np.einsum("pk,pk->p", Lm[:, i, :i], y[:, :i])) / Lm[:, i, i]
    x = np.empty_like(g)
    for i in reversed(range(q)):  # back: L^T x = y
        x[:, i] = (y[:, i] - np.einsum("pk,pk->p", Lm[:, i + 1:, i], x[:, i + 1:])) / Lm[:, i, i]
    return x, ok


class Bounds:
    """Box constraints of the scalar unknowns (rho_d >= 0 always)."""

    def __init__(self, rs_max, m_lo=1.0, m_hi=50.0):
        self.rs_max = rs_max  # (P,) float32
        self.m_lo, self.m_hi = np.float32(m_lo), np.float32(m_hi)


def _pinned(vals, g, lo, hi):
    """Unknowns at a bound whose gradient step points out of the box."""
    out = np.zeros(g.shape, dtype=bool)
    return out | ((vals <= lo) & (g <= 0)) | ((vals >= hi) & (g >= 0))


def _lm_block(L, I, w, n, rd, rs, m, rs_max, cols, bnd, max_iter, tol):
    """LM on one block of pixels, in place on n, rd, rs, m; returns (iterations,
    converged, cost)."""
    p = n.shape[0]
    q = 3 + len(cols)
    cost, A, g, t1, t2 = evaluate(L, I, w, n, rd, rs, m, jac=True, cols=cols)
    lam = np.full(p, 1e-3)
    iters = np.zeros(p, dtype=np.int32)
    conv = np.zeros(p, dtype=bool)
    act = np.arange(p)
    diag_idx = np.arange(q)
    for _ in range(max_iter):
        if act.size == 0:
            break
        na, rda, rsa, ma = n[act], rd[act], rs[act], m[act]
        Ad, ga = A[act], g[act].copy()
        # active set: an unknown at a bound with the step pointing outwards is held
        pin = np.zeros(ga.shape, dtype=bool)
        pin[:, 2] = (rda <= 0) & (ga[:, 2] <= 0)
        for j, name in enumerate(cols, start=3):
            v, lo, hi = (rsa, 0.0, rs_max[act]) if name == "rs" else (ma, bnd.m_lo, bnd.m_hi)
            pin[:, j] = _pinned(v, ga[:, j], lo, hi)
        diag = np.diagonal(Ad, axis1=1, axis2=2)
        dmp = np.maximum(diag, 1e-9 * diag.sum(1, keepdims=True) / q + 1e-30)
        Ad = Ad + (lam[act, None] * dmp)[:, :, None] * np.eye(q)
        if pin.any():
            Ad[pin[:, :, None] | pin[:, None, :]] = 0.0
            Ad[:, diag_idx, diag_idx] = np.where(pin, 1.0, Ad[:, diag_idx, diag_idx])
            ga[pin] = 0.0
        x, ok = _solve_spd(Ad, ga)
        x[~ok | ~np.isfinite(x).all(1)] = 0.0
        n2 = na + x[:, 0:1].astype(np.float32) * t1[act] + x[:, 1:2].astype(np.float32) * t2[act]
        n2 /= np.linalg.norm(n2, axis=1, keepdims=True)
        rd2 = np.maximum(rda + x[:, 2].astype(np.float32), 0.0)
        rs2, m2 = rsa, ma
        for j, name in enumerate(cols, start=3):
            if name == "rs":
                rs2 = np.clip(rsa + x[:, j].astype(np.float32), 0.0, rs_max[act])
            else:
                m2 = np.clip(ma + x[:, j].astype(np.float32), bnd.m_lo, bnd.m_hi)
        c2, A2, g2, u1, u2 = evaluate(L, I[act], w[act], n2, rd2, rs2, m2, jac=True, cols=cols)
        iters[act] += 1
        better = (c2 < cost[act]) & ok & np.isfinite(c2)
        # converged: the step is below tol in every unknown (radians for n, relative
        # to the pixel's brightness for the albedos, relative to m for m)
        scale = np.maximum(np.maximum(rda, rsa), 1e-12)
        small = ((np.hypot(x[:, 0], x[:, 1]) <= tol)
                 & (np.abs(rd2 - rda) <= tol * scale) & (np.abs(rs2 - rsa) <= tol * scale)
                 & (np.abs(m2 - ma) <= tol * ma))
        small |= lam[act] > 1e12  # no descent direction left at float precision
        ib = act[better]
        n[ib], rd[ib], rs[ib], m[ib] = n2[better], rd2[better], rs2[better], m2[better]
        cost[ib] = c2[better]
        A[ib], g[ib], t1[ib], t2[ib] = A2[better], g2[better], u1[better], u2[better]
        lam[act] = np.where(better, np.maximum(lam[act] * 0.2, 1e-9), lam[act] * 8.0)
        conv[act[small]] = True
        act = act[~small]
    return iters, conv, cost


def fit(L, I, w, n, rd, rs, m, rs_max, *, cols=("rs",), m_lo=1.0, m_hi=50.0,
        max_iter=100, tol=1e-5, block=None):
    """Fit every pixel (in place on n, rd, rs, m), block by block.

    Parameters
    ----------
    L : Lights
    I, w : (P, k) float32
    n : (P, 3) float32 unit; rd, rs, m, rs_max : (P,) float32
        Start values (overwritten) and the per-pixel upper bound on rho_s.
    cols : tuple of {"rs", "m"}
        Per-pixel unknowns besides n and rho_d; the others stay as given.

    Returns
    -------
    iterations : (P,) int32, converged : (P,) bool, cost : (P,) float64
    """
    P, k = I.shape
    block = block or max(256, BLOCK_ELEMS // max(k, 1))
    bnd = Bounds(rs_max, m_lo, m_hi)
    iters = np.zeros(P, dtype=np.int32)
    conv = np.zeros(P, dtype=bool)
    cost = np.zeros(P, dtype=np.float64)
    for lo in range(0, P, block):
        s = slice(lo, min(P, lo + block))
        nb, rdb, rsb, mb = n[s].copy(), rd[s].copy(), rs[s].copy(), m[s].copy()
        it, cv, c = _lm_block(L, I[s], w[s], nb, rdb, rsb, mb, rs_max[s], tuple(cols),
                              bnd, max_iter, tol)
        n[s], rd[s], rs[s], m[s] = nb, rdb, rsb, mb
        iters[s], conv[s], cost[s] = it, cv, c
    return iters, conv, cost


def init_rho(L, I, w, n, m, rs_max, rs=None):
    """Least-squares (rho_d, rho_s) for fixed n and m (2x2 per pixel, clipped to the
    bounds): a start that already accounts for the highlight. With ``rs`` given
    (p,), only rho_d is solved."""
    c = n @ L.Dt
    ch = np.clip(n @ L.Ht, -1.0, 1.0)
    th = np.arccos(ch)
    E = np.exp(-np.square(th * m[:, None]))
    G = (c > 0) * L.mu
    p_, e_ = G * c, G * E
    wp, we = w * p_, w * e_
    a00 = np.einsum("pk,pk->p", wp, p_, dtype=np.float64)
    a01 = np.einsum("pk,pk->p", wp, e_, dtype=np.float64)
    a11 = np.einsum("pk,pk->p", we, e_, dtype=np.float64)
    r0 = np.einsum("pk,pk->p", wp, I, dtype=np.float64)
    r1 = np.einsum("pk,pk->p", we, I, dtype=np.float64)
    if rs is not None:
        rd = (r0 - a01 * rs) / np.maximum(a00, 1e-30)
        return np.maximum(rd, 0.0).astype(np.float32), np.asarray(rs, np.float32)
    det = a00 * a11 - a01 * a01
    ok = det > 1e-9 * np.maximum(a00 * a11, 1e-30)
    sdet = np.where(ok, det, 1.0)
    rd = np.where(ok, (a11 * r0 - a01 * r1) / sdet, r0 / np.maximum(a00, 1e-30))
    rs = np.where(ok, (a00 * r1 - a01 * r0) / sdet, 0.0)
    # a negative rho_s: refit rho_d alone
    neg = rs < 0
    rd = np.where(neg, r0 / np.maximum(a00, 1e-30), rd)
    rs = np.clip(rs, 0.0, rs_max)
    return np.maximum(rd, 0.0).astype(np.float32), rs.astype(np.float32)


def reduced(L, I, w, n, rd, rs, m, cols, glob):
    """Gauss–Newton step for unknowns shared by all pixels, the per-pixel ones
    projected out.

    At per-pixel optima (gradient ~ 0 in the pixel's own unknowns ``cols`` besides
    n and rho_d), the reduced curvature of the total cost in the shared unknowns
    ``glob`` is sum_p (A_gg - A_gx A_xx^-1 A_xg) and the reduced gradient
    sum_p (g_g - A_gx A_xx^-1 g_x) (Schur complement). Returns the step
    (len(glob),) solving that system (zeros if it is singular).
    """
    P, k = I.shape
    block = max(256, BLOCK_ELEMS // max(k, 1))
    qx = 3 + len(cols)
    ng = len(glob)
    Hs = np.zeros((ng, ng))
    gs = np.zeros(ng)
    for lo in range(0, P, block):
        s = slice(lo, min(P, lo + block))
        _, A, g, _, _ = evaluate(L, I[s], w[s], n[s], rd[s], rs[s], m[s], jac=True,
                                 cols=tuple(cols) + tuple(glob))
        Axx = A[:, :qx, :qx]
        ridge = 1e-9 * np.trace(Axx, axis1=1, axis2=2) + 1e-30
        Axx = Axx + ridge[:, None, None] * np.eye(qx)
        Axg = A[:, :qx, qx:]
        sol = []
        for j in range(ng):
            u, ok = _solve_spd(Axx.copy(), Axg[:, :, j].copy())
            sol.append(np.where(ok[:, None], u, 0.0))
        v, ok = _solve_spd(Axx, g[:, :qx].copy())
        v = np.where(ok[:, None], v, 0.0)
        U = np.stack(sol, axis=2)  # (p, qx, ng)
        Hp = A[:, qx:, qx:] - np.einsum("pig,pih->pgh", Axg, U)
        gp = g[:, qx:] - np.einsum("pig,pi->pg", Axg, v)
        fin = np.isfinite(Hp).all((1, 2)) & np.isfinite(gp).all(1)
        Hs += Hp[fin].sum(0)
        gs += gp[fin].sum(0)
    try:
        step = np.linalg.solve(Hs + 1e-9 * np.trace(Hs) * np.eye(ng), gs)
    except np.linalg.LinAlgError:
        return np.zeros(ng)
    return step if np.isfinite(step).all() else np.zeros(ng)


def hemisphere(count):
    """``count`` nearly uniform unit vectors with z > 0 (Fibonacci lattice)."""
    i = np.arange(count) + 0.5
    z = 1.0 - i / count  # uniform in z on the upper hemisphere
    phi = i * np.pi * (3.0 - np.sqrt(5.0))
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _projected(a00, a01, a11, r0, r1):
    """Least (negative) explained energy of the 2x2 nonnegative LS for (rho_d, rho_s):
    returns -(r^T x) at the constrained optimum x (the cost is sum w I^2 plus this)."""
    det = a00 * a11 - a01 * a01
    ok = det > 1e-12 * (a00 * a11 + 1e-30)
    inv = 1.0 / np.where(ok, det, 1.0)
    x0 = (a11 * r0 - a01 * r1) * inv
    x1 = (a00 * r1 - a01 * r0) * inv
    both = ok & (x0 >= 0) & (x1 >= 0)
    e_both = x0 * r0 + x1 * r1
    e_d = np.where(r0 > 0, r0 * r0 / np.maximum(a00, 1e-30), 0.0)  # rho_s = 0
    e_s = np.where(r1 > 0, r1 * r1 / np.maximum(a11, 1e-30), 0.0)  # rho_d = 0
    return -np.where(both, e_both, np.maximum(e_d, e_s))


def grid_start(L, I, w, n0, m_value, count=256, rs=None):
    """Best start normal per pixel among a hemisphere grid and ``n0``.

    For every candidate normal the costs of all pixels follow from five matrix
    products with per-light tables (rho_d, and rho_s unless ``rs`` (p,) is given, are
    solved in closed form; the lobe width is fixed at ``m_value``). Returns
    (n (p, 3) float32, cost of the best candidate minus sum w I^2 (p,)).
    """
    C = hemisphere(count)
    c = C @ L.d.T.astype(np.float64)  # (J, k)
    th = np.arccos(np.clip(C @ L.h.T.astype(np.float64), -1, 1))
    lit = (c > 0) * L.mu
    Pd = (c * lit).astype(np.float32).T  # (k, J): d f / d rho_d
    Ps = (np.exp(-(m_value * th) ** 2) * lit).astype(np.float32).T
    tabs = np.concatenate([Pd * Pd, Pd * Ps, Ps * Ps, Pd, Ps], axis=1)  # (k, 5J)
    P, k = I.shape
    J = count
    block = max(64, BLOCK_ELEMS // max(count, k))
    best = np.empty(P)
    arg = np.empty(P, dtype=np.int64)
    for lo in range(0, P, block):
        s = slice(lo, min(P, lo + block))
        wb = w[s]
        a = wb @ tabs[:, :3 * J]
        r = (wb * I[s]) @ tabs[:, 3 * J:]
        a00, a01, a11, r0, r1 = a[:, :J], a[:, J:2 * J], a[:, 2 * J:], r[:, :J], r[:, J:]
        if rs is None:
            e = _projected(a00, a01, a11, r0, r1)
        else:  # rho_s given: cost - sum w I^2 = rs^2 a11 - 2 rs r1 - max(r0 - rs a01, 0)^2 / a00
            q = rs[s, None].astype(np.float32)
            t = np.maximum(r0 - q * a01, 0.0)
            e = q * (q * a11 - 2.0 * r1) - t * t / np.maximum(a00, 1e-30)
        arg[s] = np.argmin(e, axis=1)
        best[s] = e[np.arange(e.shape[0]), arg[s]]
    # the given start competes with the grid
    m = np.full(P, m_value, dtype=np.float32)
    rd, rs0 = init_rho(L, I, w, n0, m, np.full(P, np.inf, dtype=np.float32), rs=rs)
    own = evaluate(L, I, w, n0, rd, rs0, m) - np.einsum("pk,pk->p", w * I, I, dtype=np.float64)
    use_grid = best < own
    n = np.where(use_grid[:, None], C[arg].astype(np.float32), n0)
    return n, np.where(use_grid, best, own)
