"""Batched Levenberg–Marquardt for the per-pixel Lambert + Torrance–Sparrow model.

The model of observation i at one pixel (distant light direction d_i, power mu_i,
orthographic view v = (0, 0, 1), bisector h_i = (d_i + v) / |d_i + v|):

    f_i = mu_i [rho_d (d_i . n) + rho_s exp(-m^2 theta_i^2)]   if d_i . n > 0, else 0,
    theta_i = arccos(h_i . n).

Unknowns per pixel: the unit normal n (two tangent-plane angles), rho_d and,
optionally, rho_s and m. Every pixel's problem is independent; all are solved at
once, in blocks of pixels that fit in cache; within a block every iteration works on
the still unconverged pixels only.

Layout: pixels last. Observations and weights are (k, p) float32, normals (3, p),
normal matrices (q, q, p) float64, so that every operation runs over long contiguous
pixel rows. The normal equations are formed without the (k, p, q) Jacobian: the
n-gradient of f_i is G_i (rho_d d_i + kappa B_i h_i) with per-pixel scalars, so each
n-block of J^T W J is a matrix product of a per-light table ((6, k) for d d^T, ...)
with one (k, p) array.
"""
from __future__ import annotations

import numpy as np

__all__ = ["Lights", "evaluate", "fit", "init_rho", "reduced", "predict", "chunks"]

#: (k * p) float32 elements per block: a few MB of working set
BLOCK_ELEMS = 1 << 16
_IU = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))
_SYM_FLAT = np.array([0, 1, 2, 1, 3, 4, 2, 4, 5])  # 3x3 entries -> the 6 unique ones


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
        self.unit = bool(np.all(mu == 1.0))
        self.mu_col = self.mu[:, None]
        self.mu2_col = (mu * mu).astype(f32)[:, None]
        dd = d[:, :, None] * d[:, None, :]
        hh = h[:, :, None] * h[:, None, :]
        dh = d[:, :, None] * h[:, None, :]
        self.DDt = np.ascontiguousarray(dd[:, _IU[0], _IU[1]].T.astype(f32))  # (6, k)
        self.HHt = np.ascontiguousarray(hh[:, _IU[0], _IU[1]].T.astype(f32))
        self.DHt = np.ascontiguousarray((dh + dh.transpose(0, 2, 1))[:, _IU[0], _IU[1]].T.astype(f32))
        self.Dt = np.ascontiguousarray(self.d.T)  # (3, k)
        self.dh = np.concatenate([self.d, self.h])  # (2k, 3)
        self.Ht = np.ascontiguousarray(self.h.T)


def _tangents(n):
    """Orthonormal tangent basis (t1, t2) (3, p) of unit normals n (3, p).

    Branch-free and without a square root (Duff et al., "Building an orthonormal
    basis, revisited", JCGT 2017): smooth in n except across nz = 0.
    """
    nx, ny, nz = n
    sign = np.copysign(np.float32(1.0), nz)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    t1 = np.empty_like(n)
    t2 = np.empty_like(n)
    t1[0] = 1.0 + sign * nx * nx * a
    t1[1] = sign * b
    t1[2] = -sign * nx
    t2[0] = b
    t2[1] = sign + ny * ny * a
    t2[2] = -ny
    return t1, t2


def _shade(L, n, m):
    """c = d . n, theta, E = exp(-m^2 theta^2), ch = h . n; all (k, p) float32."""
    cc = L.dh @ n  # one product for d . n and h . n
    c, ch = cc[:L.k], cc[L.k:]
    np.clip(ch, -1.0, 1.0, out=ch)
    th = np.arccos(ch)
    E = np.multiply(th, th)
    E *= -(m * m)
    np.exp(E, out=E)
    return c, ch, th, E


def predict(L, n, rd, rs, m):
    """Model images f (k, p) float32 for normals n (3, p) and per-pixel rd, rs, m."""
    c, _, _, E = _shade(L, n, m)
    f = c * rd
    E *= rs
    f += E
    f *= c > 0
    if not L.unit:
        f *= L.mu_col
    return f


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
        tangent basis (t1, t2) used.
    cols : tuple of {"rs", "m"}
        Per-pixel unknowns after (angle, angle, rho_d), in this order.

    Returns
    -------
    cost : (p,) float64 = sum_i w_i (I_i - f_i)^2; with ``jac`` also (A, g, t1, t2).
    """
    c, ch, th, E = _shade(L, n, m)
    lit = c > 0
    f = c * rd
    tmp = E * rs
    f += tmp
    f *= lit
    if not L.unit:
        f *= L.mu_col
    r = np.subtract(I, f, out=f)
    wr = np.multiply(w, r, out=tmp)
    cost = np.einsum("kp,kp->p", wr, r).astype(np.float64)
    if not jac:
        return cost
    q = 3 + len(cols)
    p = n.shape[1]
    # d f / d n = G (rd d + kappa B h), G = mu lit, B = E theta / sin(theta)
    s = np.sin(th, out=ch)  # ch is not needed any more
    np.maximum(s, 1e-7, out=s)  # theta ~ 0: theta / sin -> 1; theta ~ pi: E ~ 0
    B = np.divide(th, s, out=s)
    B *= E
    kappa = rs * 2.0 * m * m
    Gw = np.multiply(w, lit, dtype=np.float32)  # w G^2
    Gr = np.multiply(wr, lit, out=wr)  # w G r
    if not L.unit:
        Gw *= L.mu2_col
        Gr *= L.mu_col
    GwB = Gw * B
    J = [c]  # d f / d rho_d, up to G
    for name in cols:
        if name == "rs":
            J.append(E)
        else:  # d f / d m = -2 m rs theta^2 E
            dm = np.multiply(th, th, out=th)
            dm *= E
            dm *= -2.0 * m * rs
            J.append(dm)
    A = np.empty((q, q, p), dtype=np.float64)
    g = np.empty((q, p), dtype=np.float64)
    M = L.DDt @ Gw
    M *= rd * rd
    M += (L.DHt @ GwB) * (rd * kappa)
    GwB *= B
    M += (L.HHt @ GwB) * (kappa * kappa)  # (6, p): sum w G^2 (rd d + kappa B h)(...)^T
    GwB = np.multiply(Gw, B, out=GwB)
    # vectors v (3, p) such that sum w G^2 (rd d + kappa B h) x_i = v . (...)
    V = [(L.Dt @ Gr) * rd + (L.Ht @ (Gr * B)) * kappa]  # the n-gradient
    for col in J:
        V.append((L.Dt @ (Gw * col)) * rd + (L.Ht @ (GwB * col)) * kappa)
    t1, t2 = _tangents(n)
    Mf = M[_SYM_FLAT].reshape(3, 3, p)
    Vs = np.stack(V)  # (q - 1, 3, p)
    for i, ti in enumerate((t1, t2)):
        Mt = np.einsum("abp,bp->ap", Mf, ti)
        A[i, i] = np.einsum("ap,ap->p", Mt, ti)
        if i == 0:
            A[0, 1] = A[1, 0] = np.einsum("ap,ap->p", Mt, t2)
        proj = np.einsum("vap,ap->vp", Vs, ti)
        g[i] = proj[0]
        A[i, 2:] = proj[1:]
        A[2:, i] = proj[1:]
    for i, ci in enumerate(J):
        g[2 + i] = np.einsum("kp,kp->p", Gr, ci)
        Gci = Gw * ci
        for j in range(i, len(J)):
            A[2 + i, 2 + j] = A[2 + j, 2 + i] = np.einsum("kp,kp->p", Gci, J[j])
    return cost, A, g, t1, t2


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


def _step(L, I, w, n, rd, rs, m, rs_max, A, g, t1, t2, lam, active, cols, m_lo, m_hi, tol):
    """One damped Gauss–Newton step for a chunk of pixels.

    Returns the candidate (n, rd, rs, m), its (cost, A, g, t1, t2) (None if no pixel
    needed it; cost inf where not evaluated), ``ok`` (a finite step was taken) and
    ``small`` (the step is below ``tol`` in every unknown).
    """
    q = 3 + len(cols)
    Ad, ga = A.astype(np.float64), g.astype(np.float64)
    # Marquardt damping (scaled by the diagonal, floored for unknowns carrying no
    # information, e.g. m where rho_s = 0)
    diag = np.array([A[i, i] for i in range(q)])
    floor = 1e-9 * diag.sum(0) / q + 1e-30
    for i in range(q):
        Ad[i, i] += lam * np.maximum(diag[i], floor)
    # active set: an unknown at a bound whose step points outwards is held there
    pins = [(2, (rd <= 0) & (ga[2] <= 0))]
    for j, name in enumerate(cols, start=3):
        v, lo, hi = (rs, 0.0, rs_max) if name == "rs" else (m, m_lo, m_hi)
        pins.append((j, ((v <= lo) & (ga[j] <= 0)) | ((v >= hi) & (ga[j] >= 0))))
    for j, pin in pins:
        if pin.any():
            Ad[j, :, pin] = 0.0
            Ad[:, j, pin] = 0.0
            Ad[j, j, pin] = 1.0
            ga[j, pin] = 0.0
    x, ok = _solve_spd(Ad, ga)
    ok &= np.isfinite(x).all(0)
    x[:, ~ok] = 0.0
    xf = x.astype(np.float32)
    n2 = n + xf[0] * t1 + xf[1] * t2  # on the sphere: tangent step, then normalise
    n2 /= np.sqrt((n2 * n2).sum(0))
    rd2 = np.maximum(rd + xf[2], 0.0)
    rs2, m2 = rs, m
    for j, name in enumerate(cols, start=3):
        if name == "rs":
            rs2 = np.clip(rs + xf[j], 0.0, rs_max)
        else:
            m2 = np.clip(m + xf[j], m_lo, m_hi)
    # converged: the step is below tol in every unknown (radians for n, relative to
    # the pixel's albedo for rho_d and rho_s, relative to m for m); such a pixel is
    # at its optimum within tol and its candidate is not evaluated
    scale = np.maximum(np.maximum(rd, rs), 1e-12)
    small = ((np.hypot(x[0], x[1]) <= tol) & (np.abs(rd2 - rd) <= tol * scale)
             & (np.abs(rs2 - rs) <= tol * scale) & (np.abs(m2 - m) <= tol * m))
    small |= lam > 1e12  # no descent direction left at float precision
    need = active & ~small
    cand = (n2, rd2, rs2, m2)
    if not need.any():
        return cand, None, ok, small
    if need.mean() > 0.85:
        return cand, evaluate(L, I, w, n2, rd2, rs2, m2, jac=True, cols=cols), ok, small
    sel = np.flatnonzero(need)
    c2, A2, g2, u1, u2 = evaluate(L, I[:, sel], w[:, sel], n2[:, sel], rd2[sel], rs2[sel],
                                  m2[sel], jac=True, cols=cols)
    p = n.shape[1]
    cost = np.full(p, np.inf)
    cost[sel] = c2
    A = np.zeros((q, q, p), dtype=A2.dtype)
    A[..., sel] = A2
    g = np.zeros((q, p), dtype=g2.dtype)
    g[:, sel] = g2
    t1n, t2n = np.zeros_like(n), np.zeros_like(n)
    t1n[:, sel], t2n[:, sel] = u1, u2
    return cand, (cost, A, g, t1n, t2n), ok, small


def fit(L, I, w, n, rd, rs, m, rs_max, *, cols=(), m_lo=1.0, m_hi=50.0, max_iter=100,
        tol=1e-5, block=None):
    """Levenberg–Marquardt on every pixel (in place on n, rd, rs, m).

    Each iteration runs over the still unconverged pixels in cache-sized chunks; the
    working set is compacted as pixels converge, so late iterations cost little.

    Parameters
    ----------
    L : Lights
    I, w : (k, P) float32
    n : (3, P) float32 unit; rd, rs, m, rs_max : (P,) float32
        Start values (overwritten) and the per-pixel upper bound on rho_s.
    cols : tuple of {"rs", "m"}
        Per-pixel unknowns besides n and rho_d; the others stay as given.

    Returns
    -------
    iterations : (P,) int32, converged : (P,) bool, cost : (P,) float64
    """
    k, P = I.shape
    cols = tuple(cols)
    q = 3 + len(cols)
    block = block or max(1024, BLOCK_ELEMS // max(k, 1))
    m_lo, m_hi = np.float32(m_lo), np.float32(m_hi)
    iters = np.zeros(P, dtype=np.int32)
    conv = np.zeros(P, dtype=bool)
    cost = np.zeros(P, dtype=np.float64)
    # working set (compacted copies once pixels converge); state in working order
    widx = np.arange(P)
    Iw, ww, rsmw = I, w, rs_max
    nw, rdw, rsw, mw = n, rd, rs, m
    cw = cost
    A = np.empty((q, q, P), dtype=np.float32)  # float32 storage halves the memory
    g = np.empty((q, P), dtype=np.float32)
    t1 = np.empty((3, P), dtype=np.float32)
    t2 = np.empty((3, P), dtype=np.float32)
    def first(lo):
        s = slice(lo, lo + block)
        cw[s], A[..., s], g[:, s], t1[:, s], t2[:, s] = evaluate(
            L, Iw[:, s], ww[:, s], nw[:, s], rdw[s], rsw[s], mw[s], jac=True, cols=cols)

    for lo in range(0, P, block):
        first(lo)
    lam = np.full(P, 1e-3)
    active = np.ones(P, dtype=bool)
    itw = np.zeros(P, dtype=np.int32)
    convw = np.zeros(P, dtype=bool)

    def write_back():
        n[:, widx], rd[widx], rs[widx], m[widx] = nw, rdw, rsw, mw
        cost[widx], iters[widx], conv[widx] = cw, itw, convw

    def step(lo):  # one LM iteration on one block (blocks are independent)
        s = slice(lo, lo + block)
        a = active[s]
        if not a.any():
            return
        cand, new, ok, small = _step(
            L, Iw[:, s], ww[:, s], nw[:, s], rdw[s], rsw[s], mw[s], rsmw[s], A[..., s],
            g[:, s], t1[:, s], t2[:, s], lam[s], a, cols, m_lo, m_hi, tol)
        if new is None:
            better = np.zeros_like(a)
        else:
            c2, A2, g2, u1, u2 = new
            better = a & ~small & ok & (c2 < cw[s]) & np.isfinite(c2)
            for dst, src in ((nw[:, s], cand[0]), (rdw[s], cand[1]), (rsw[s], cand[2]),
                             (mw[s], cand[3]), (cw[s], c2), (A[..., s], A2), (g[:, s], g2),
                             (t1[:, s], u1), (t2[:, s], u2)):
                if src is not dst:
                    np.copyto(dst, src, where=better)
        ls = lam[s]
        ls *= np.where(better, 0.2, np.where(a, 8.0, 1.0))
        np.maximum(ls, 1e-9, out=ls)
        itw[s] += a
        done = a & small
        # a step below tol is taken without evaluating it (the Gauss-Newton model
        # is exact to second order there): one evaluation less per pixel
        take = done & ok
        if take.any():
            for dst, src in ((nw[:, s], cand[0]), (rdw[s], cand[1]), (rsw[s], cand[2]),
                             (mw[s], cand[3])):
                if src is not dst:
                    np.copyto(dst, src, where=take)
        convw[s] |= done
        active[s] &= ~done

    for _ in range(max_iter):
        if not active.any():
            break
        for lo in range(0, widx.size, block):
            step(lo)
        na = int(active.sum())
        if 0 < na < 0.5 * widx.size:  # compact the working set
            if nw is n:
                nw, rdw, rsw, mw, cw = n.copy(), rd.copy(), rs.copy(), m.copy(), cost.copy()
            write_back()
            keep = np.flatnonzero(active)
            widx = widx[keep]
            Iw, ww, rsmw = Iw[:, keep], ww[:, keep], rsmw[keep]
            nw, rdw, rsw, mw, cw = nw[:, keep], rdw[keep], rsw[keep], mw[keep], cw[keep]
            A, g, t1, t2 = A[..., keep], g[:, keep], t1[:, keep], t2[:, keep]
            lam, itw, convw = lam[keep], itw[keep], convw[keep]
            active = np.ones(na, dtype=bool)
    if nw is not n:
        write_back()
    else:
        iters[:], conv[:] = itw, convw
    return iters, conv, cost


def chunks(P, k):
    """Slices of the P pixels, about ``BLOCK_ELEMS`` observations each."""
    step = max(1024, BLOCK_ELEMS // max(k, 1))
    return [slice(lo, min(P, lo + step)) for lo in range(0, P, step)]


def init_rho(L, I, w, n, m, rs_max, rs=None, *, wII=None):
    """Least-squares (rho_d, rho_s) for fixed n and m (2x2 per pixel, clipped to the
    bounds): a start that already accounts for the highlight. With ``rs`` given
    (p,), only rho_d is solved. Returns float32 (rd, rs), (p,) each; with ``wII``
    (p,) = sum_i w_i I_i^2 given, also the cost at that (n, rd, rs, m) (float64,
    from the same sums: one shading pass instead of two)."""
    P = n.shape[1]
    rd_out = np.empty(P, dtype=np.float32)
    rs_out = np.empty(P, dtype=np.float32)
    cost = None if wII is None else np.empty(P)
    for s in chunks(P, I.shape[0]):
        out = _init_rho(L, I[:, s], w[:, s], n[:, s], m[s], rs_max[s],
                        None if rs is None else rs[s], None if wII is None else wII[s])
        rd_out[s], rs_out[s] = out[:2]
        if cost is not None:
            cost[s] = out[2]
    return (rd_out, rs_out) if cost is None else (rd_out, rs_out, cost)


def weighted_energy(I, w):
    """sum_i w_i I_i^2 per pixel, (p,) float64."""
    out = np.empty(I.shape[1])
    for s in chunks(I.shape[1], I.shape[0]):
        out[s] = np.einsum("kp,kp->p", w[:, s] * I[:, s], I[:, s])
    return out


def _init_rho(L, I, w, n, m, rs_max, rs, wII=None):
    c, _, _, E = _shade(L, n, m)
    G = (c > 0) * L.mu_col
    c *= G
    E *= G  # c, E: d f / d rho_d, d f / d rho_s
    wc = w * c
    a00 = np.einsum("kp,kp->p", wc, c).astype(np.float64)
    a01 = np.einsum("kp,kp->p", wc, E).astype(np.float64)
    r0 = np.einsum("kp,kp->p", wc, I).astype(np.float64)
    a11 = r1 = None
    if rs is None or wII is not None:
        wE = w * E
        a11 = np.einsum("kp,kp->p", wE, E).astype(np.float64)
        r1 = np.einsum("kp,kp->p", wE, I).astype(np.float64)
    if rs is not None:
        rs = np.asarray(rs, np.float64)
        rd = np.maximum((r0 - a01 * rs) / np.maximum(a00, 1e-30), 0.0)
        return _with_cost(rd, rs, a00, a01, a11, r0, r1, wII)
    det = a00 * a11 - a01 * a01
    ok = det > 1e-9 * np.maximum(a00 * a11, 1e-30)
    sdet = np.where(ok, det, 1.0)
    rd = np.where(ok, (a11 * r0 - a01 * r1) / sdet, r0 / np.maximum(a00, 1e-30))
    rs = np.where(ok, (a00 * r1 - a01 * r0) / sdet, 0.0)
    neg = rs < 0  # a negative rho_s: rho_d alone
    rd = np.where(neg, r0 / np.maximum(a00, 1e-30), rd)
    rs = np.clip(rs, 0.0, rs_max)
    return _with_cost(np.maximum(rd, 0.0), rs, a00, a01, a11, r0, r1, wII)


def _with_cost(rd, rs, a00, a01, a11, r0, r1, wII):
    """(rd, rs) as float32, and the cost sum w (I - rd c - rs E)^2 from the sums."""
    out = rd.astype(np.float32), rs.astype(np.float32)
    if wII is None:
        return out
    rd, rs = out[0].astype(np.float64), out[1].astype(np.float64)
    cost = wII - 2 * (rd * r0 + rs * r1) + rd * rd * a00 + 2 * rd * rs * a01 + rs * rs * a11
    return out + (np.maximum(cost, 0.0),)


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
    block = max(1024, BLOCK_ELEMS // max(k, 1))
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
