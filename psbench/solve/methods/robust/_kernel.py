"""Compiled per-pixel kernels of the robust methods (``trim``, the M-estimators, ``robust``).

A kernel runs, pixel by pixel, the whole per-pixel computation -- order statistics, the
trimmed or reweighted 3x3 normal equations, the IRLS iterations with their per-pixel
stopping rule -- in one pass over the pixel's observations, where the numpy versions made a chain of ``(n, k)``
temporaries per step. Pixels are independent (no reduction across pixels), so blocks
of pixels run on numba's threads (psbench selects numba's fork-safe threading layer,
:mod:`psbench._shared.numba_setup`; psbench's runs pin one thread) and the results do not
depend on the thread count.

The 3x3 normal equations are accumulated in float32 (as the numpy versions' matrix
products did) and solved in float64 by :func:`psbench.solve._sym3.solve_sym3` (the
singularity rule of every psbench solve); solutions are stored in float32.
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

from ..._sym3 import solve_sym3

__all__ = ["trim_rows", "irls_m", "HUBER", "CAUCHY", "TUKEY", "WEIGHT_FUNCTIONS"]

#: weight functions of :func:`irls_m` (its ``kind``), and estimator name -> code
HUBER, CAUCHY, TUKEY = 0, 1, 2
WEIGHT_FUNCTIONS = {"huber": HUBER, "cauchy": CAUCHY, "tukey": TUKEY}
#: pixels per block (scratch rows are allocated once per block)
CHUNK = 512
#: rows up to this length rank every observation by counting (k^2 / 2 comparisons),
#: longer ones find the order statistics by bisection (~64 k comparisons)
SHORT = 64


@njit(cache=True, nogil=True, error_model="numpy")
def _keys(x, key):
    """Integer keys of float32 values, ordered as the values are (the sign-magnitude
    bits of a negative value flipped); -0.0 must have been made +0.0 (``x + 0``)."""
    bits = x.view(np.int32)
    for i in range(x.shape[0]):
        b = bits[i]
        key[i] = b ^ ((b >> 31) & 0x7FFFFFFF)


@njit(cache=True, nogil=True, error_model="numpy")
def _kth(key, q):
    """The key of the q-th smallest entry (0-based), by bisection over the key range:
    ~32 branch-free counting passes the compiler vectorises, where a sort or a
    quickselect branches on every comparison."""
    n = key.shape[0]
    lo = np.int64(key[0])
    hi = lo
    for j in range(n):
        v = np.int64(key[j])
        lo = min(lo, v)
        hi = max(hi, v)
    while lo < hi:
        mid = np.int32((lo + hi) >> 1)
        c = 0
        for j in range(n):
            c += key[j] <= mid
        up = c > q                     # selects, not a (mispredicted) branch
        hi = np.int64(mid) if up else hi
        lo = lo if up else np.int64(mid) + 1
    return lo


@njit(cache=True, nogil=True, error_model="numpy")
def _below_eq(x, xi):
    """(entries of x below xi, entries at most xi): a branch-free count."""
    lt = 0
    le = 0
    for j in range(x.shape[0]):
        lt += x[j] < xi
        le += x[j] <= xi
    return lt, le


@njit(cache=True, nogil=True, error_model="numpy")
def _below(x, xi):
    """Number of entries of x strictly below xi."""
    c = 0
    for j in range(x.shape[0]):
        c += x[j] < xi
    return c


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"reassoc", "contract"})
def _solve(I, w, O, St, out):
    """Weighted least squares of one pixel: (sum w_i s_i s_i^T) b = sum w_i I_i s_i,
    from the unique entries of s_i s_i^T ``O`` (6, k) and ``St`` (3, k), float32
    (the sums vectorise over the observations).

    Writes b into ``out`` (3,) and returns True, or returns False (``out`` untouched)
    where the normal matrix is singular (the rule of :mod:`psbench.solve._sym3`)."""
    a00 = a01 = a02 = a11 = a12 = a22 = np.float32(0.0)
    r0 = r1 = r2 = np.float32(0.0)
    for i in range(I.shape[0]):
        wi = w[i]
        a00 += wi * O[0, i]
        a01 += wi * O[1, i]
        a02 += wi * O[2, i]
        a11 += wi * O[3, i]
        a12 += wi * O[4, i]
        a22 += wi * O[5, i]
        wI = wi * I[i]
        r0 += wI * St[0, i]
        r1 += wI * St[1, i]
        r2 += wI * St[2, i]
    return solve_sym3(np.float64(a00), np.float64(a01), np.float64(a02), np.float64(a11),
                   np.float64(a12), np.float64(a22), np.float64(r0), np.float64(r1),
                   np.float64(r2), out)


@njit(cache=True, nogil=True, error_model="numpy")
def _abs_residuals(I, V, all_valid, St, b, out):
    """|I_i - s_i . b| in float32, +inf where the observation is not valid."""
    b0, b1, b2 = b[0], b[1], b[2]
    for i in range(I.shape[0]):
        r = abs(I[i] - (b0 * St[0, i] + b1 * St[1, i] + b2 * St[2, i]))
        out[i] = r if (all_valid or V[i]) else np.inf


@njit(cache=True, nogil=True, error_model="numpy")
def _trim_row(I, V, all_valid, m, dark, bright, x, key, keep):
    """Rank trimming of one pixel (see :class:`~.trim.TrimOptions`): fills ``keep``
    (k,) float32 with 0 / 1 and returns the kept count.

    With s the sorted valid intensities, an observation is kept when it lies above
    s[nd - 1] and below s[m - nb] (ties with a dropped value are dropped)."""
    k = I.shape[0]
    red = max(m - 3, 0)
    nd = int(np.floor(dark * red + 0.5))
    nb = int(np.floor(bright * red + 0.5))
    if all_valid and nd == 0 and nb == 0:
        keep[:] = 1.0
        return k
    for i in range(k):
        x[i] = (I[i] + np.float32(0.0)) if (all_valid or V[i]) else np.inf
    # kept: at least nd valid values below it and at most m - nb at or below it;
    # branch-free per observation (the outcome is data-dependent); not valid = +inf,
    # never kept, nor are infinite values unless every observation is valid (as the
    # comparisons with +-inf bounds of the numpy version did)
    top = m - nb
    h = 0
    if k <= SHORT:
        for i in range(k):
            xi = x[i]
            lt, le = _below_eq(x, xi)
            ok = (lt >= nd) & (le <= top) & (all_valid | (abs(xi) < np.inf))
            keep[i] = np.float32(ok)
            h += ok
    else:
        _keys(x, key)
        lo = _kth(key, nd - 1) if nd > 0 else np.int64(-(1 << 40))
        hi = _kth(key, top) if nb > 0 else np.int64(1 << 40)
        for i in range(k):
            ok = (key[i] > lo) & (key[i] < hi) & (all_valid | (abs(x[i]) < np.inf))
            keep[i] = np.float32(ok)
            h += ok
    if h < min(3, m):
        # ties with a dropped value left fewer than three: the exact rank window,
        # ties broken by image order
        h = 0
        for i in range(k):
            keep[i] = 0.0
            if not (all_valid or V[i]):
                continue
            xi = x[i]
            rank = _below(x, xi)
            for q in range(i):
                rank += x[q] == xi
            if rank >= nd and rank < m - nb:
                keep[i] = 1.0
                h += 1
    return h


@njit(cache=True, nogil=True, error_model="numpy")
def _concentrate_row(I, V, all_valid, O, St, h, b, a, key, keep):
    """One least-trimmed-squares concentration step: keep the ``h`` observations of
    smallest |residual| of ``b`` (ties with the h-th kept) and solve again (``b``
    kept where the solve is singular)."""
    _abs_residuals(I, V, all_valid, St, b, a)
    hh = max(h, 1)
    if a.shape[0] <= SHORT:
        for i in range(a.shape[0]):
            keep[i] = np.float32(_below(a, a[i]) < hh)
    else:
        _keys(a, key)
        t = _kth(key, hh - 1)
        for i in range(a.shape[0]):
            keep[i] = np.float32(key[i] <= t)
    _solve(I, keep, O, St, b)


@njit(cache=True, nogil=True, error_model="numpy")
def _gather(I, V, all_valid, p, Ip, Vp):
    """Pixel p's observations (and validity) from the (k, n) layout into contiguous
    rows; returns its number of valid observations."""
    k = I.shape[0]
    for i in range(k):
        Ip[i] = I[i, p]
    if all_valid:
        return k
    m = 0
    for i in range(k):
        Vp[i] = V[i, p]
        m += V[i, p]
    return m


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def trim_rows(I, V, all_valid, O, St, P, dark, bright, steps, half, b_out, keep_out):
    """Rank-trimmed least squares and ``steps`` concentration steps for every pixel.

    Parameters
    ----------
    I : (k, n) float32
        Intensities, images x pixels (a pixel's observations are gathered into a
        contiguous row: the per-pixel loops then run along it).
    V : (k, n) bool
        Valid observations (ignored when ``all_valid``).
    all_valid : bool
    O : (6, k) float32, St : (3, k) float32
        Unique entries of s_i s_i^T (xx, xy, xz, yy, yz, zz) and the illumination
        vectors s_i.
    P : (3, k) float32
        pinv(S): the plain least-squares solution where the trimmed solve is singular.
    dark, bright : float
        Fractions of the redundant observations dropped at each end.
    steps : int
        Concentration steps after the rank-trimmed solve.
    half : bool
        The steps keep floor(m / 2) + 1 observations (False: as many as the trimming).
    b_out : (n, 3) float32, keep_out : (k, n) bool
        Solutions and the observations of each pixel's final solve.
    """
    k, n = I.shape
    for c in prange((n + CHUNK - 1) // CHUNK):  # blocks on numba's threads
        Ip = np.empty(k, dtype=np.float32)
        Vp = np.ones(k, dtype=np.bool_)
        s = np.empty(k, dtype=np.float32)
        a = np.empty(k, dtype=np.float32)
        keep = np.empty(k, dtype=np.float32)
        key = np.empty(k, dtype=np.int32)
        b = np.empty(3, dtype=np.float32)
        for p in range(c * CHUNK, min(n, (c + 1) * CHUNK)):
            m = _gather(I, V, all_valid, p, Ip, Vp)
            h = _trim_row(Ip, Vp, all_valid, m, dark, bright, s, key, keep)
            if not _solve(Ip, keep, O, St, b):
                for j in range(3):
                    acc = np.float32(0.0)
                    for i in range(k):
                        acc += P[j, i] * Ip[i]
                    b[j] = acc
            hh = m // 2 + 1 if half else h
            for _ in range(steps):
                _concentrate_row(Ip, Vp, all_valid, O, St, hh, b, a, key, keep)
            b_out[p, 0], b_out[p, 1], b_out[p, 2] = b[0], b[1], b[2]
            for i in range(k):
                keep_out[i, p] = keep[i] != 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _mad(r, V, all_valid, s, key, floor):
    """max(1.4826 * median |r| over the valid observations, floor), float32 (the
    median of an even count averages the two middle values; 0 without any)."""
    j = 0
    for i in range(r.shape[0]):
        if all_valid or V[i]:
            s[j] = abs(r[i])
            j += 1
    if j == 0:
        return floor
    v = s[:j]
    lo, hi = (j - 1) // 2, j // 2
    a = b = np.float32(0.0)
    if j <= SHORT:
        # rank counting: v[i] is the q-th smallest when lt <= q < le
        for i in range(j):
            lt, le = _below_eq(v, v[i])
            if lt <= lo < le:
                a = v[i]
            if lt <= hi < le:
                b = v[i]
    else:
        kv = key[:j]
        _keys(v, kv)
        klo = _kth(kv, lo)
        khi = _kth(kv, hi)
        for i in range(j):
            if kv[i] == klo:
                a = v[i]
            if kv[i] == khi:
                b = v[i]
    med = np.float32(0.5) * (a + b)
    return max(med * np.float32(1.4826), floor)


@njit(cache=True, nogil=True, error_model="numpy", fastmath={"reassoc", "contract"})
def _reweight_solve(I, vf, O, St, b, inv, kind, w, out):
    """One IRLS step of one pixel: residuals of ``b``, weights w(u) of u = r * inv
    (0 where ``vf`` is 0) into ``w``, and the weighted solve into ``out`` (left as it
    is where singular). Simple loops (the estimator chosen outside them) that the
    compiler vectorises."""
    one = np.float32(1.0)
    zero = np.float32(0.0)
    b0, b1, b2 = b[0], b[1], b[2]
    k = I.shape[0]
    for i in range(k):
        w[i] = (I[i] - (b0 * St[0, i] + b1 * St[1, i] + b2 * St[2, i])) * inv
    if kind == HUBER:
        for i in range(k):
            w[i] = vf[i] / max(abs(w[i]), one)
    elif kind == CAUCHY:
        for i in range(k):
            w[i] = vf[i] / (w[i] * w[i] + one)
    else:
        for i in range(k):
            t = max(one - w[i] * w[i], zero)
            w[i] = vf[i] * (t * t)
    return _solve(I, w, O, St, out)


@njit(cache=True, nogil=True, parallel=True, error_model="numpy")
def irls_m(I, V, all_valid, O, St, b0, c, kind, rescale, floor, conv_floor, tol, n_iter,
           b_out, w_out, inl_out, it_out, conv_out, sigma_out):
    """IRLS M-estimate of every pixel with a per-pixel MAD scale and early stop.

    Per pixel: sigma = 1.4826 median |r| of the start ``b0`` (>= ``floor``); then
    until the solution moves by at most ``tol`` times its length (>= ``conv_floor``)
    or ``n_iter`` iterations: u = r / (c sigma) (sigma re-estimated from r first when
    ``rescale``), weights w(u) of ``kind`` (Huber min(1, 1/|u|), Cauchy 1 / (1 + u^2),
    Tukey max(0, 1 - u^2)^2), 0 where not valid, and the weighted solve (the previous
    solution kept where it is singular).

    Layout as :func:`trim_rows` (``I`` and ``V`` (k, n)). Outputs: b_out (n, 3)
    float32, w_out (k, n) float32 (weights of the last solve), inl_out (k, n) bool
    (valid and |r| <= c sigma of the final solution), it_out (n,) int32, conv_out
    (n,) bool, sigma_out (n,) float32 (the final scale).
    """
    k, n = I.shape
    one = np.float32(1.0)
    for ch in prange((n + CHUNK - 1) // CHUNK):  # blocks on numba's threads
        Ip = np.empty(k, dtype=np.float32)
        Vp = np.ones(k, dtype=np.bool_)
        s = np.empty(k, dtype=np.float32)
        r = np.empty(k, dtype=np.float32)
        w = np.empty(k, dtype=np.float32)
        vf = np.ones(k, dtype=np.float32)
        key = np.empty(k, dtype=np.int32)
        b = np.empty(3, dtype=np.float32)
        bn = np.empty(3, dtype=np.float32)
        for p in range(ch * CHUNK, min(n, (ch + 1) * CHUNK)):
            _gather(I, V, all_valid, p, Ip, Vp)
            if not all_valid:
                for i in range(k):
                    vf[i] = np.float32(Vp[i])
            b[0], b[1], b[2] = b0[p, 0], b0[p, 1], b0[p, 2]
            it = 0
            conv = False
            sigma = floor
            while True:
                if it == 0 or rescale:
                    for i in range(k):
                        r[i] = Ip[i] - (b[0] * St[0, i] + b[1] * St[1, i] + b[2] * St[2, i])
                    sigma = _mad(r, Vp, all_valid, s, key, floor)
                bn[0], bn[1], bn[2] = b[0], b[1], b[2]
                _reweight_solve(Ip, vf, O, St, b, one / (c * sigma), kind, w, bn)
                d0, d1, d2 = bn[0] - b[0], bn[1] - b[1], bn[2] - b[2]
                step = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                size = np.sqrt(bn[0] * bn[0] + bn[1] * bn[1] + bn[2] * bn[2])
                b[0], b[1], b[2] = bn[0], bn[1], bn[2]
                it += 1
                conv = step <= tol * max(size, conv_floor)
                if conv or it >= n_iter:
                    break
            b_out[p, 0], b_out[p, 1], b_out[p, 2] = b[0], b[1], b[2]
            cs = c * sigma
            for i in range(k):
                w_out[i, p] = w[i]
                inl_out[i, p] = (vf[i] != 0) & (abs(Ip[i] - (b[0] * St[0, i] + b[1] * St[1, i]
                                                             + b[2] * St[2, i])) <= cs)
            it_out[p] = it
            conv_out[p] = conv
            sigma_out[p] = sigma
