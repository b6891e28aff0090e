"""Compiled per-pixel kernels of tsfit: the whole Levenberg–Marquardt fit of a pixel
in registers.

The model and the step are those documented in :mod:`psbench.solve.methods.tsfit._lm`:
per pixel the unknowns (two tangent angles of the normal, rho_d, and optionally
rho_s and m), the normal equations J^T W J and J^T W r accumulated light by light,
Marquardt damping scaled by the diagonal, an active set for unknowns at their
bounds, a Cholesky solve, accept if the cost drops, stop when a step is below the
tolerance (taken without evaluating it).

Speed: a pixel's observations are loaded once for its whole fit; the loops over
lights are branch-free so that the compiler vectorises them across lights (which
is why arccos and exp are polynomials here: a libm call would stop that), and every
helper is inlined (a call with array arguments costs reference counting per pixel).
Each pixel is independent: ``prange`` runs over blocks of pixels with no reduction
across pixels, so results do not depend on the number of threads. Arithmetic is
float64 inside a pixel (sums may be reassociated across lights); inputs and the
state are float32.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit, prange
from numba.core import types
from numba.extending import intrinsic

__all__ = ["lm_fit", "evaluate", "init_rho", "predict", "tables"]

#: pixels per prange task (the scratch arrays are allocated once per block)
BLOCK = 256
#: floating-point freedom of the kernels: reassociation (so sums over lights
#: vectorise) and fused multiply-add; no assumption about NaN or infinities
FASTMATH = {"reassoc", "contract"}
#: arccos(x) = sqrt(1 - x) (a0 + a1 x + ... + a7 x^7) on [0, 1], absolute error
#: <= 2e-8, relative <= 2e-8 (Abramowitz & Stegun 4.4.45-46): as accurate as the
#: float32 arccos the model was evaluated with by numpy
_ACOS = (1.5707963050, -0.2145988016, 0.0889789874, -0.0501743046, 0.0308918810,
         -0.0170881256, 0.0066700901, -0.0012624911)
#: exp(-a) is taken as 0 for a >= EXP_CUT (below 4e-44: far below the float32
#: resolution of any observation)
EXP_CUT = 100.0
_LOG2E, _LN2_HI, _LN2_LO = 1.4426950408889634, 0.6931471803691238, 1.9082149292705877e-10
#: the IEEE float64 exponent bias and the position of the exponent field
_BIAS, _MANT = 1023, 52
#: rows of the light table (:func:`tables`)
_DX, _DY, _DZ, _HX, _HY, _HZ, _MU = range(7)
#: 15 entries of the lower triangle of the 5 x 5 normal matrix, then the 5 of g
NSUM = 20


def tables(d, h, mu):
    """Light table (7, k) float64: rows d_x, d_y, d_z, h_x, h_y, h_z, mu."""
    d, h = np.asarray(d, np.float64), np.asarray(h, np.float64)
    return np.ascontiguousarray(np.vstack([d.T, h.T, np.asarray(mu, np.float64)[None]]))


@njit(cache=True, nogil=True, fastmath=FASTMATH, inline="always")
def _acos(x):
    """arccos of x in [-1, 1] (see ``_ACOS``)."""
    a0, a1, a2, a3, a4, a5, a6, a7 = _ACOS
    ax = abs(x)
    r = math.sqrt(1.0 - ax) * (a0 + ax * (a1 + ax * (a2 + ax * (a3 + ax * (a4 + ax * (
        a5 + ax * (a6 + ax * a7)))))))
    return r if x >= 0.0 else math.pi - r


@intrinsic
def _bits_as_float(typingctx, x):
    """The float64 whose IEEE bit pattern is the int64 x (an LLVM bitcast: no memory
    access, so a loop that uses it still vectorises)."""
    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], context.get_value_type(types.float64))
    return types.float64(types.int64), codegen


@njit(cache=True, nogil=True, fastmath=FASTMATH, inline="always")
def _expm(a):
    """exp(-a) for a >= 0: 2^-j exp(-r), |r| <= ln2 / 2, by a degree-9 Taylor
    polynomial (relative error < 3e-10); 0 beyond EXP_CUT.

    2^-j is built from its exponent bits (exact: j <= EXP_CUT log2(e) + 1 = 145, a
    normal float64) rather than read from a table, whose lookup is a gather that
    keeps the surrounding loops scalar (the held-out kernel ran 2x slower with it)."""
    b = min(a, EXP_CUT)
    j = int(b * _LOG2E + 0.5)
    jf = float(j)
    r = jf * _LN2_HI - b + jf * _LN2_LO  # -(b - j ln2)
    p = 1.0 + r * (1.0 + r * (0.5 + r * (1.0 / 6 + r * (1.0 / 24 + r * (1.0 / 120 + r * (
        1.0 / 720 + r * (1.0 / 5040 + r * (1.0 / 40320 + r * (1.0 / 362880)))))))))
    return p * _bits_as_float((_BIAS - j) << _MANT) if a < EXP_CUT else 0.0


@njit(cache=True, nogil=True, fastmath=FASTMATH, inline="always")
def _model(lt, nx, ny, nz, rd, rs, m2):
    """The model's value for one light at the unit normal n with rho_d, rho_s and m^2:
    mu [rd (d . n) + rs exp(-m^2 theta^2)], 0 in self shadow. ``lt``: the light's
    column of the table as a tuple (dx, dy, dz, hx, hy, hz, mu), read once per light
    by the caller (outside its pixel loop, which then vectorises)."""
    dx, dy, dz, hx, hy, hz, mu = lt
    c = dx * nx + dy * ny + dz * nz
    ch = min(max(hx * nx + hy * ny + hz * nz, -1.0), 1.0)
    th = _acos(ch)
    v = mu * (rd * c + rs * _expm(m2 * th * th))
    return v if c > 0.0 else 0.0


@njit(cache=True, nogil=True, inline="always")
def _light(tab, i):
    """Column i of the light table as the tuple :func:`_model` takes."""
    return (tab[_DX, i], tab[_DY, i], tab[_DZ, i], tab[_HX, i], tab[_HY, i], tab[_HZ, i],
            tab[_MU, i])


@njit(cache=True, nogil=True, fastmath=FASTMATH, inline="always")
def _tangents(nx, ny, nz, t):
    """Orthonormal tangent basis t (2, 3) at the unit normal n, branch-free up to the
    sign of nz and without a square root (Duff et al., JCGT 2017)."""
    sign = 1.0 if nz >= 0.0 else -1.0
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    t[0, 0] = 1.0 + sign * nx * nx * a
    t[0, 1] = sign * b
    t[0, 2] = -sign * nx
    t[1, 0] = b
    t[1, 1] = sign + ny * ny * a
    t[1, 2] = -ny


@njit(cache=True, nogil=True, fastmath=FASTMATH, inline="always")
def _cost(tab, Ip, wp, nx, ny, nz, rd, rs, m, C, CH, TH, E, R):
    """Weighted cost of one pixel; keeps per light the clamped cosine C (0 in self
    shadow), h . n, theta, the lobe E and the residual R for :func:`_sums`."""
    k = Ip.shape[0]
    m2 = m * m
    cost = 0.0
    for i in range(k):
        c = tab[_DX, i] * nx + tab[_DY, i] * ny + tab[_DZ, i] * nz
        ch = min(max(tab[_HX, i] * nx + tab[_HY, i] * ny + tab[_HZ, i] * nz, -1.0), 1.0)
        th = _acos(ch)
        e = _expm(m2 * th * th)
        lit = c > 0.0
        f = tab[_MU, i] * (rd * c + rs * e) if lit else 0.0
        r = Ip[i] - f
        cost += wp[i] * r * r
        C[i] = c if lit else 0.0
        CH[i] = ch
        TH[i] = th
        E[i] = e
        R[i] = r
    return cost


@njit(cache=True, nogil=True, fastmath=FASTMATH, inline="always")
def _sums(tab, wp, rd, rs, m, t, C, CH, TH, E, R, S):
    """S (20,) = the lower triangle of J^T W J (5 x 5, row by row) and J^T W r (5)
    in the unknowns (t1 angle, t2 angle, rho_d, rho_s, m), from :func:`_cost`'s
    per-light values. d f / d n = mu (rho_d d + kappa B h) where lit, with
    kappa = 2 m^2 rho_s, B = E theta / sin(theta)."""
    k = wp.shape[0]
    kappa = 2.0 * m * m * rs
    dm = -2.0 * m * rs
    t00, t01, t02, t10, t11, t12 = t[0, 0], t[0, 1], t[0, 2], t[1, 0], t[1, 1], t[1, 2]
    a00 = a10 = a11 = a20 = a21 = a22 = a30 = a31 = a32 = a33 = 0.0
    a40 = a41 = a42 = a43 = a44 = g0 = g1 = g2 = g3 = g4 = 0.0
    for i in range(k):
        c = C[i]
        G = tab[_MU, i] if c > 0.0 else 0.0
        ch, th, e = CH[i], TH[i], E[i]
        s = max(math.sqrt(max(1.0 - ch * ch, 0.0)), 1e-7)  # theta ~ 0: theta / s -> 1
        B = kappa * e * th / s
        gx = G * (rd * tab[_DX, i] + B * tab[_HX, i])
        gy = G * (rd * tab[_DY, i] + B * tab[_HY, i])
        gz = G * (rd * tab[_DZ, i] + B * tab[_HZ, i])
        j0 = gx * t00 + gy * t01 + gz * t02
        j1 = gx * t10 + gy * t11 + gz * t12
        j2 = G * c
        j3 = G * e
        j4 = dm * th * th * e * G
        wi = wp[i]
        wr = wi * R[i]
        g0 += wr * j0
        g1 += wr * j1
        g2 += wr * j2
        g3 += wr * j3
        g4 += wr * j4
        w0, w1, w2, w3, w4 = wi * j0, wi * j1, wi * j2, wi * j3, wi * j4
        a00 += w0 * j0
        a10 += w1 * j0
        a11 += w1 * j1
        a20 += w2 * j0
        a21 += w2 * j1
        a22 += w2 * j2
        a30 += w3 * j0
        a31 += w3 * j1
        a32 += w3 * j2
        a33 += w3 * j3
        a40 += w4 * j0
        a41 += w4 * j1
        a42 += w4 * j2
        a43 += w4 * j3
        a44 += w4 * j4
    S[0], S[1], S[2], S[3], S[4] = a00, a10, a11, a20, a21
    S[5], S[6], S[7], S[8], S[9] = a22, a30, a31, a32, a33
    S[10], S[11], S[12], S[13], S[14] = a40, a41, a42, a43, a44
    S[15], S[16], S[17], S[18], S[19] = g0, g1, g2, g3, g4


@njit(cache=True, nogil=True, inline="always")
def _crosses(tab, nx, ny, nz, px, py, pz):
    """Whether some light is in front of one of the normals n, p and not the other."""
    for i in range(tab.shape[1]):
        c = tab[_DX, i] * nx + tab[_DY, i] * ny + tab[_DZ, i] * nz
        c2 = tab[_DX, i] * px + tab[_DY, i] * py + tab[_DZ, i] * pz
        if (c > 0.0) != (c2 > 0.0):
            return True
    return False


@njit(cache=True, nogil=True, inline="always")
def _unpack(S, ix, q, A, g):
    """A (q, q) and g (q,) of the unknowns ``ix[:q]`` from the full sums S."""
    for a in range(q):
        ia = ix[a]
        g[a] = S[15 + ia]
        for b in range(a + 1):
            ib = ix[b]
            v = S[ia * (ia + 1) // 2 + ib] if ia >= ib else S[ib * (ib + 1) // 2 + ia]
            A[a, b] = v
            A[b, a] = v


@njit(cache=True, nogil=True, inline="always")
def _load(I, w, p, Ip, wp):
    for i in range(Ip.shape[0]):
        Ip[i] = I[i, p]
        wp[i] = w[i, p]


@njit(cache=True, nogil=True, inline="always")
def _pin(Ad, x, j, q):
    for i in range(q):
        Ad[j, i] = 0.0
        Ad[i, j] = 0.0
    Ad[j, j] = 1.0
    x[j] = 0.0


@njit(cache=True, nogil=True, inline="always")
def _solve(Ad, x, q):
    """Cholesky solve of Ad x = x in place (Ad overwritten); False if not SPD or
    the solution is not finite."""
    for j in range(q):
        s = Ad[j, j]
        for t in range(j):
            s -= Ad[j, t] * Ad[j, t]
        if not s > 0.0:
            return False
        s = math.sqrt(s)
        Ad[j, j] = s
        for i in range(j + 1, q):
            acc = Ad[i, j]
            for t in range(j):
                acc -= Ad[i, t] * Ad[j, t]
            Ad[i, j] = acc / s
    for i in range(q):
        acc = x[i]
        for t in range(i):
            acc -= Ad[i, t] * x[t]
        x[i] = acc / Ad[i, i]
    for i in range(q - 1, -1, -1):
        acc = x[i]
        for t in range(i + 1, q):
            acc -= Ad[t, i] * x[t]
        x[i] = acc / Ad[i, i]
    for i in range(q):
        if not math.isfinite(x[i]):
            return False
    return True


@njit(cache=True, parallel=True, nogil=True, fastmath=FASTMATH)
def lm_fit(tab, I, w, n, rd_, rs_, m_, rs_max, fit_rs, fit_m, m_lo, m_hi, max_iter, tol,
           iters, conv, cost):
    """Levenberg–Marquardt on every pixel, in place on n (3, P), rd, rs, m (P,);
    fills iters, conv, cost (P,). tab: :func:`tables`; I, w (k, P); fit_rs, fit_m:
    0 or 1 (which of rho_s, m are per-pixel unknowns)."""
    k, P = I.shape
    q = 3 + fit_rs + fit_m
    ir, im = 3, 3 + fit_rs
    nb = (P + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        Ip, wp = np.empty(k), np.empty(k)
        C, CH, TH, E, R = np.empty(k), np.empty(k), np.empty(k), np.empty(k), np.empty(k)
        S = np.empty(NSUM)
        A, Ad = np.empty((5, 5)), np.empty((5, 5))
        g, x = np.empty(5), np.empty(5)
        t = np.empty((2, 3))
        ix = np.array([0, 1, 2, 3 if fit_rs else 4, 4])
        for p in range(blk * BLOCK, min(P, (blk + 1) * BLOCK)):
            _load(I, w, p, Ip, wp)
            nx, ny, nz = float(n[0, p]), float(n[1, p]), float(n[2, p])
            rd, rs, m = float(rd_[p]), float(rs_[p]), float(m_[p])
            rsm = float(rs_max[p])
            # One evaluation site for the cost and one for the sums: each inlined
            # helper is compiled once (three copies of _cost took most of the
            # kernel's compile time). The first pass evaluates the start; later
            # passes evaluate the proposed step p.
            px, py, pz, rd2, rs2, m2 = nx, ny, nz, rd, rs, m
            c0 = 0.0
            lam = 1e-3
            it = 0
            done = False
            first = True
            final = False  # a small step across a terminator: evaluated, then stop
            ok = True
            while True:
                c2 = _cost(tab, Ip, wp, px, py, pz, rd2, rs2, m2, C, CH, TH, E, R)
                if first:
                    accept = True
                elif final:
                    accept = c2 < c0
                else:
                    accept = ok and c2 < c0 and math.isfinite(c2)
                if accept:
                    nx, ny, nz, rd, rs, m, c0 = px, py, pz, rd2, rs2, m2, c2
                if final:
                    done = True
                    break
                if accept:
                    _tangents(nx, ny, nz, t)
                    _sums(tab, wp, rd, rs, m, t, C, CH, TH, E, R, S)
                    _unpack(S, ix, q, A, g)
                if not first:
                    lam = max(lam * 0.2 if accept else lam * 8.0, 1e-9)
                first = False
                if it >= max_iter:
                    break
                # Marquardt damping scaled by the diagonal, floored for unknowns
                # without information (e.g. m where rho_s = 0)
                tr = 0.0
                for i in range(q):
                    tr += A[i, i]
                floor = 1e-9 * tr / q + 1e-30
                for i in range(q):
                    for j in range(q):
                        Ad[i, j] = A[i, j]
                    Ad[i, i] += lam * max(A[i, i], floor)
                    x[i] = g[i]
                # active set: an unknown at a bound whose step points outwards stays
                if rd <= 0.0 and g[2] <= 0.0:
                    _pin(Ad, x, 2, q)
                if fit_rs and ((rs <= 0.0 and g[ir] <= 0.0) or (rs >= rsm and g[ir] >= 0.0)):
                    _pin(Ad, x, ir, q)
                if fit_m and ((m <= m_lo and g[im] <= 0.0) or (m >= m_hi and g[im] >= 0.0)):
                    _pin(Ad, x, im, q)
                ok = _solve(Ad, x, q)
                if not ok:
                    for i in range(q):
                        x[i] = 0.0
                # the step on the sphere: along the tangent plane, then normalise
                px = nx + x[0] * t[0, 0] + x[1] * t[1, 0]
                py = ny + x[0] * t[0, 1] + x[1] * t[1, 1]
                pz = nz + x[0] * t[0, 2] + x[1] * t[1, 2]
                nn = math.sqrt(px * px + py * py + pz * pz)
                px, py, pz = px / nn, py / nn, pz / nn
                rd2 = max(rd + x[2], 0.0)
                rs2 = min(max(rs + x[ir], 0.0), rsm) if fit_rs else rs
                m2 = min(max(m + x[im], m_lo), m_hi) if fit_m else m
                # converged: a step below tol in every unknown (radians for n,
                # relative to the albedo for rho_d and rho_s, relative to m for m)
                scale = max(max(rd, rs), 1e-12)
                small = (math.sqrt(x[0] * x[0] + x[1] * x[1]) <= tol
                         and abs(rd2 - rd) <= tol * scale and abs(rs2 - rs) <= tol * scale
                         and abs(m2 - m) <= tol * m)
                it += 1
                if small or lam > 1e12:  # lam > 1e12: no descent direction left
                    # a step below tol is taken without evaluating it (the model is
                    # smooth to second order there) unless it moves the normal across
                    # a self-shadow terminator, where the model jumps by the lobe
                    if ok and small and _crosses(tab, nx, ny, nz, px, py, pz):
                        final = True
                        continue
                    if ok and small:
                        nx, ny, nz, rd, rs, m = px, py, pz, rd2, rs2, m2
                    done = True
                    break
            n[0, p], n[1, p], n[2, p] = nx, ny, nz
            rd_[p], rs_[p], m_[p] = rd, rs, m
            iters[p] = it
            conv[p] = done
            cost[p] = c0


@njit(cache=True, parallel=True, nogil=True, fastmath=FASTMATH)
def evaluate(tab, I, w, n, rd, rs, m, jac, cost, S, t):
    """Cost (P,) and, with ``jac``, the sums S (P, 20) (see :func:`_sums`) and the
    tangent basis t (P, 2, 3) at the given parameters."""
    k, P = I.shape
    nb = (P + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        Ip, wp = np.empty(k), np.empty(k)
        C, CH, TH, E, R = np.empty(k), np.empty(k), np.empty(k), np.empty(k), np.empty(k)
        tt = np.empty((2, 3))
        for p in range(blk * BLOCK, min(P, (blk + 1) * BLOCK)):
            _load(I, w, p, Ip, wp)
            nx, ny, nz = float(n[0, p]), float(n[1, p]), float(n[2, p])
            mm = float(m[p])
            cost[p] = _cost(tab, Ip, wp, nx, ny, nz, float(rd[p]), float(rs[p]), mm, C, CH,
                            TH, E, R)
            if jac:
                _tangents(nx, ny, nz, tt)
                _sums(tab, wp, float(rd[p]), float(rs[p]), mm, tt, C, CH, TH, E, R, S[p])
                for i in range(2):
                    for j in range(3):
                        t[p, i, j] = tt[i, j]


@njit(cache=True, parallel=True, nogil=True, fastmath=FASTMATH)
def init_rho(tab, I, w, n, m, rs_max, rs_fixed, has_rs, want_cost, rd_out, rs_out, cost):
    """Least-squares (rho_d, rho_s) for fixed n, m per pixel (2 x 2, clipped to the
    bounds; rho_d alone where ``has_rs``, rho_s then taken from ``rs_fixed``), and
    (``want_cost``) the cost there from the same sums.

    Lights outer, pixels inner: the (k, P) observations are read along their rows
    and the pixel loop vectorises (2-3x faster than a loop over lights per pixel)."""
    k, P = I.shape
    nb = (P + BLOCK - 1) // BLOCK
    for blk in prange(nb):
        lo, hi = blk * BLOCK, min(P, (blk + 1) * BLOCK)
        acc = np.zeros((6, hi - lo))  # a00, a01, a11, r0, r1, wII per pixel
        for i in range(k):
            dx, dy, dz = tab[_DX, i], tab[_DY, i], tab[_DZ, i]
            hx, hy, hz, mu = tab[_HX, i], tab[_HY, i], tab[_HZ, i], tab[_MU, i]
            for p in range(lo, hi):
                nx, ny, nz = float(n[0, p]), float(n[1, p]), float(n[2, p])
                m2 = float(m[p]) ** 2
                wi = float(w[i, p])
                Ii = float(I[i, p])
                c = dx * nx + dy * ny + dz * nz
                ch = min(max(hx * nx + hy * ny + hz * nz, -1.0), 1.0)
                th = _acos(ch)
                G = mu if c > 0.0 else 0.0
                c *= G  # d f / d rho_d, d f / d rho_s
                e = _expm(m2 * th * th) * G
                j = p - lo
                acc[5, j] += wi * Ii * Ii
                acc[0, j] += wi * c * c
                acc[1, j] += wi * c * e
                acc[2, j] += wi * e * e
                acc[3, j] += wi * c * Ii
                acc[4, j] += wi * e * Ii
        for p in range(lo, hi):
            j = p - lo
            a00, a01, a11 = acc[0, j], acc[1, j], acc[2, j]
            r0, r1, wII = acc[3, j], acc[4, j], acc[5, j]
            if has_rs:
                rs = float(rs_fixed[p])
                rd = max((r0 - a01 * rs) / max(a00, 1e-30), 0.0)
            else:
                det = a00 * a11 - a01 * a01
                if det > 1e-9 * max(a00 * a11, 1e-30):
                    rd = (a11 * r0 - a01 * r1) / det
                    rs = (a00 * r1 - a01 * r0) / det
                else:
                    rd = r0 / max(a00, 1e-30)
                    rs = 0.0
                if rs < 0.0:  # a negative rho_s: rho_d alone
                    rd = r0 / max(a00, 1e-30)
                rs = min(max(rs, 0.0), float(rs_max[p]))
                rd = max(rd, 0.0)
            rd_out[p] = rd
            rs_out[p] = rs
            if want_cost:
                rd, rs = float(rd_out[p]), float(rs_out[p])  # the float32 values returned
                cc = (wII - 2.0 * (rd * r0 + rs * r1) + rd * rd * a00
                      + 2.0 * rd * rs * a01 + rs * rs * a11)
                cost[p] = max(cc, 0.0)


@njit(cache=True, parallel=True, nogil=True, fastmath=FASTMATH)
def predict(tab, n, rd, rs, m, out):
    """Model images out (k, P) float32 for normals n (3, P) and per-pixel rd, rs, m
    (a task per light, each along its whole row: every value is computed on its own,
    and runs of 256 pixels per light, as before, were 2.7x slower)."""
    k = tab.shape[1]
    P = n.shape[1]
    for i in prange(k):
        lt = _light(tab, i)
        for p in range(P):
            out[i, p] = _model(lt, float(n[0, p]), float(n[1, p]), float(n[2, p]),
                               float(rd[p]), float(rs[p]), float(m[p]) ** 2)
