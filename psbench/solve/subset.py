"""Subset masks (Section 3.3.3): Coleman-Jain (CJ), extended non-Lambert quadruples
(xNL) and whole-image RANSAC (RA).

Every function is vectorized over pixels; only subsets (triplets, quadruples) and
pattern runs are looped over.

Conventions shared by this module
---------------------------------
* **Dynamic range.** Thresholds are fractions of the stack's dynamic range
  ``D = mean_i (max I_i - min I_i)`` (the mean over images of each image's range,
  :func:`dynamic_range`). One scalar serves every image so that linear relations
  between intensities of different images (the NL relation a . I = 0) survive the
  scaling.
* **Lambertian error (NL / xNL).** For four lights, ``a`` is the null vector of the
  (4, 3) matrix of their illumination vectors (a_1 s_1 + ... + a_4 s_4 = 0, Eq. 3.3),
  computed in closed form from the 3x3 cofactors and normalised to ``|a| = 1``; the
  error is ``(a . I / D)^2`` (Eq. 3.5-3.6). With this scaling Gaussian noise of
  standard deviation ``sigma * D`` gives an error of about ``sigma^2`` whatever the
  lights, so ``t_nl`` reads as a squared fraction of the dynamic range (Table 5.2:
  0.01-0.04, i.e. 10-20 % of the range).
* **Reflection test (Re, Eq. 3.8 / 5.1).** Observation i is a probable highlight
  where the angle between the normal and the bisector ``h_i = (d_i + v)/|d_i + v|``
  (v = (0, 0, 1)) is below ``t_re`` degrees.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from .._shared.checks import PsbenchError, as_images, as_S
from . import kernel

__all__ = ["n_ransac", "ransac", "cj", "xnl", "xnl_pattern", "xnl_resolve", "null_vector",
           "dynamic_range", "t_re_default", "reflection_flags", "RA_THRESHOLD", "CJ_THRESHOLD"]

#: default RANSAC consensus threshold, fraction of the dynamic range (see :func:`ransac`)
RA_THRESHOLD = 0.1
#: default Coleman-Jain threshold on std/mean of the four triplet albedos (see :func:`cj`)
CJ_THRESHOLD = 0.1


# --------------------------------------------------------------------------- helpers
def _as_S(S, k=None, name="S"):
    return as_S(S, k, name)


def dynamic_range(images):
    """Scalar dynamic range D = mean over images of (max - min), floored at 1e-12.

    Parameters
    ----------
    images : (k, H, W) float

    Returns
    -------
    float
    """
    k = images.shape[0]
    flat = images.reshape(k, -1)
    D = float(np.mean(flat.max(axis=1) - flat.min(axis=1)))
    return max(D, 1e-12)


def n_ransac(p=0.99, eps=0.5, s=3):
    """Number of random subsets for RANSAC, Eq. 3.11 (rounded up).

    ``N = log(1 - p) / log(1 - (1 - eps)^s)``; the defaults give 35.
    """
    if not 0.0 < p < 1.0:
        raise PsbenchError(f"p must be in (0, 1), got {p}")
    if not 0.0 <= eps < 1.0:
        raise PsbenchError(f"eps must be in [0, 1), got {eps}")
    if int(s) != s or s < 1:
        raise PsbenchError(f"s must be a positive integer, got {s}")
    q = (1.0 - eps) ** s
    if q >= 1.0:
        return 1
    return int(math.ceil(math.log(1.0 - p) / math.log(1.0 - q) - 1e-12))


def null_vector(S4):
    """Closed-form null vector of four 3-vectors (Eq. 3.3), normalised to |a| = 1.

    ``a_i = (-1)^i det(S without row i)`` satisfies ``sum_i a_i s_i = 0`` (Laplace
    expansion of a 4x4 determinant with a repeated column).

    Parameters
    ----------
    S4 : (4, 3) or (4, N, 3) array_like
        Rows s_1..s_4 (optionally per pixel).

    Returns
    -------
    a : (4,) or (4, N) float
        Zero where the four vectors span less than a plane (``|a|`` ~ 0).
    """
    S4 = np.asarray(S4)
    s = [S4[i] for i in range(4)]
    a = np.stack([_det3(s[1], s[2], s[3]), -_det3(s[0], s[2], s[3]),
                  _det3(s[0], s[1], s[3]), -_det3(s[0], s[1], s[2])])
    nrm = np.sqrt((a * a).sum(axis=0))
    ok = nrm > 1e-9
    return np.where(ok, a / np.where(ok, nrm, 1.0), 0.0).astype(S4.dtype, copy=False)


def _det3(x, y, z):
    """det[x; y; z] for (..., 3) arrays (rows x, y, z)."""
    return (x[..., 0] * (y[..., 1] * z[..., 2] - y[..., 2] * z[..., 1])
            - x[..., 1] * (y[..., 0] * z[..., 2] - y[..., 2] * z[..., 0])
            + x[..., 2] * (y[..., 0] * z[..., 1] - y[..., 1] * z[..., 0]))


def t_re_default(S):
    """Reflection threshold of Eq. 5.1, ``min(z, (90 - z)/2, p)`` in degrees.

    For a general (multi-ring) layout: ``z`` is the smallest light zenith in the first
    term and the largest in the second (the binding cases), ``p`` the smallest polar
    gap between lights (lights within 1 degree of the axis are ignored for ``p``).
    E.g. 45x8 -> 22.5, 30x8+60x8 -> 15.
    """
    S = _as_S(S)
    d = S / np.linalg.norm(S, axis=1, keepdims=True)
    zen = np.degrees(np.arccos(np.clip(d[:, 2], -1.0, 1.0)))
    pol = np.sort(np.degrees(np.arctan2(d[:, 1], d[:, 0]))[zen > 1.0] % 360.0)
    if pol.size >= 2:
        gaps = np.diff(np.concatenate([pol, pol[:1] + 360.0]))
        gaps = gaps[gaps > 1e-6]
        p = float(gaps.min()) if gaps.size else 360.0
    else:
        p = 360.0
    return float(min(zen.min(), (90.0 - zen.max()) / 2.0, p))


def reflection_flags(normals, S, t_re):
    """Re test (Eq. 3.8 with the corrected sense): True = probable highlight.

    Parameters
    ----------
    normals : (H, W, 3) float
    S : (k, 3) array_like
    t_re : float
        Degrees; observation i is flagged where angle(n, h_i) < t_re, with h_i the
        bisector of the light direction and the view direction (0, 0, 1).

    Returns
    -------
    (k, H, W) bool
    """
    S = _as_S(S)
    d = S / np.linalg.norm(S, axis=1, keepdims=True)
    h = d + np.array([0.0, 0.0, 1.0])
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    H, W, _ = normals.shape
    c = h.astype(np.float32) @ normals.reshape(-1, 3).T.astype(np.float32)
    return (c > np.float32(np.cos(np.radians(t_re)))).reshape(-1, H, W)


# --------------------------------------------------------------------------- RANSAC
def _triplets(S, n_subsets, seed):
    k = S.shape[0]
    combos = np.array(list(itertools.combinations(range(k), 3)), dtype=np.intp)
    # drop degenerate triplets (coplanar with the origin / duplicated lights)
    sv = np.linalg.svd(S[combos], compute_uv=False)
    good = sv[:, -1] > 1e-6 * sv[:, 0]
    combos = combos[good]
    if combos.shape[0] == 0:
        raise PsbenchError("S: every triplet of lights is degenerate; RANSAC cannot run")
    N = n_ransac() if n_subsets is None else int(n_subsets)
    if N < 1:
        raise PsbenchError(f"n_subsets must be >= 1, got {n_subsets}")
    if combos.shape[0] <= N:
        return combos
    rng = np.random.default_rng(seed)
    pick = np.sort(rng.choice(combos.shape[0], size=N, replace=False))
    return combos[pick]


def ransac(images, S, *, threshold=None, n_subsets=None, seed=0, chunk=8192):
    """Whole-image RANSAC subset mask (Section 3.3.3.3).

    Triplets of images are drawn for the whole image: all ``C(k,3)`` triplets when
    that is at most ``n_subsets`` (default :func:`n_ransac` = 35, so k <= 7 uses all),
    else ``n_subsets`` distinct random triplets (seeded; degenerate triplets are never
    drawn). Each triplet is solved exactly per pixel (3x3 inverse), the residuals of
    all k observations are computed, and the consensus set is ``|I - L| < threshold * D``
    with D the stack's dynamic range (:func:`dynamic_range`). Each pixel keeps the
    largest consensus set seen; ties go to the smaller sum of |residual| over the set.

    Parameters
    ----------
    images : (k, H, W) array_like
    S : (k, 3) array_like or Layout
    threshold : float, optional
        Consensus threshold as a fraction of D. Default :data:`RA_THRESHOLD` = 0.1:
        twice the 5 % noise of the thesis's images and above Table 5.2's highlight
        fractions k_Hi (0.03-0.06), so a consensus rejects highlights and shadows
        (errors of a large part of the range) but keeps ~95 % of noisy inliers.
    n_subsets : int, optional
        Number of triplets N (Eq. 3.11); default 35.
    seed : int
        Seed of the triplet draw.

    Returns
    -------
    valid : (k, H, W) bool
        The consensus set of each pixel (always contains its generating triplet).
    """
    images = as_images(images, min_count=3)
    k, H, W = images.shape
    S = _as_S(S, k)
    thr = RA_THRESHOLD if threshold is None else float(threshold)
    if not thr > 0:
        raise PsbenchError(f"threshold must be > 0 (fraction of the dynamic range), got {threshold}")
    thr = np.float32(thr * dynamic_range(images))
    trip = _triplets(S, n_subsets, seed)
    T = trip.shape[0]
    # G[t] = (S inv(S_t) E_t - Id)[others]: signed residuals of the k-3 images outside
    # triplet t (the triplet's own residuals are 0 by construction) in one product
    G = np.zeros((T, k - 3, k))
    others = np.empty((T, k - 3), dtype=np.intp)
    for t, tr in enumerate(trip):
        o = np.setdiff1d(np.arange(k), tr)
        others[t] = o
        Gt = np.zeros((k, k))
        Gt[:, tr] = S @ np.linalg.inv(S[tr])
        Gt -= np.eye(k)
        G[t] = Gt[o]
    G = G.reshape(T * (k - 3), k).astype(np.float32)
    big = np.float32(k) * thr * np.float32(1.01)  # > any in-consensus residual sum
    I2 = images.reshape(k, -1)
    Np = I2.shape[1]
    best_t = np.empty(Np, dtype=np.intp)
    if k > 3:
        for lo in range(0, Np, chunk):
            hi = min(Np, lo + chunk)
            r = (G @ I2[:, lo:hi]).reshape(T, k - 3, hi - lo)
            np.abs(r, out=r)
            # |r| inside the consensus, big outside: the sum over images orders the
            # triplets by (consensus size desc, residual sum asc) lexicographically
            np.putmask(r, r >= thr, big)
            best_t[lo:hi] = np.argmin(r.sum(axis=1), axis=0)
    else:
        best_t[:] = 0
    valid = np.ones((k, Np), dtype=bool)
    for t in range(T):
        sel = np.flatnonzero(best_t == t)
        if sel.size == 0 or k == 3:
            continue
        r = G[t * (k - 3):(t + 1) * (k - 3)] @ I2[:, sel]
        valid[others[t][:, None], sel[None, :]] = np.abs(r) < thr
    return valid.reshape(k, H, W)


# --------------------------------------------------------------------------- CJ
def cj(images, S, *, t_cj=None):
    """Coleman-Jain four-image mask (Section 3.3.3.1) -> albedo-scaled normals.

    The four triplets of the four images are solved exactly (3x3 inverses). Where the
    relative spread of the four albedos ``std(rho) / mean(rho)`` is below ``t_cj`` no
    highlight is assumed and the four solutions ``rho_t n_t`` are averaged (i.e. the
    normals are averaged with albedo weights, and the result's albedo is the norm of
    that mean); otherwise the triplet with the smallest albedo is taken (a highlight
    raises the albedo of the three triplets that contain it).

    Parameters
    ----------
    images : (4, H, W) array_like
    S : (4, 3) array_like or Layout
    t_cj : float, optional
        Threshold on std/mean of the albedos (population std); default
        :data:`CJ_THRESHOLD` = 0.1 (noise-free Lambertian pixels give 0; 5 % noise
        gives a few percent).

    Returns
    -------
    b : (H, W, 3) float32
        rho * n.
    """
    images = as_images(images, min_count=1)
    k, H, W = images.shape
    if k != 4:
        raise PsbenchError(f"images: the CJ mask needs exactly 4 images, got {k}")
    S = _as_S(S, k)
    t = CJ_THRESHOLD if t_cj is None else float(t_cj)
    if not t >= 0:
        raise PsbenchError(f"t_cj must be >= 0, got {t_cj}")
    I2 = images.reshape(4, -1)
    bs, rhos = [], []
    for drop in range(4):
        tr = [i for i in range(4) if i != drop]
        St = S[tr]
        if np.linalg.svd(St, compute_uv=False)[-1] < 1e-9:
            raise PsbenchError(f"S: lights {tr} are degenerate; CJ needs every triplet independent")
        b = np.linalg.inv(St).astype(np.float32) @ I2[tr]  # (3, N)
        bs.append(b)
        rhos.append(np.sqrt((b * b).sum(axis=0)))
    # elementwise over the four candidates (reductions along a length-4 leading axis
    # and take_along_axis are several times slower at 512^2)
    mean = (rhos[0] + rhos[1] + rhos[2] + rhos[3]) * np.float32(0.25)
    var = sum((r - mean) ** 2 for r in rhos) * np.float32(0.25)
    agree = np.sqrt(var) <= np.float32(t) * np.maximum(mean, np.float32(1e-12))
    chosen, rmin = bs[0], rhos[0]  # the smallest-albedo triplet (first on ties)
    for b, r in zip(bs[1:], rhos[1:]):
        smaller = r < rmin
        chosen = np.where(smaller, b, chosen)
        rmin = np.where(smaller, r, rmin)
    out = np.where(agree, (bs[0] + bs[1] + bs[2] + bs[3]) * np.float32(0.25), chosen)
    return np.ascontiguousarray(out.T).reshape(H, W, 3).astype(np.float32, copy=False)


# --------------------------------------------------------------------------- xNL
def xnl_pattern(images, S, *, t_nl, order=None):
    """Binary Lambertian pattern of the sorted consecutive quadruples (Section 3.3.3.2).

    Parameters
    ----------
    images : (k, H, W) float32, k >= 4
    S : (k, 3)
    t_nl : float
        Threshold on the Lambertian error ``(a . I / D)^2`` (|a| = 1; module docs).
    order : (k, H, W) int, optional
        Per-pixel order darkest -> brightest (computed when None).

    Returns
    -------
    pattern : (k-3, H, W) bool
        pattern[j] True = quadruple of sorted positions j..j+3 is Lambertian.
    error : (k-3, H, W) float32
        The Lambertian errors.
    order : (k, H, W) intp
    """
    k, H, W = images.shape
    S = _as_S(S, k)
    D = np.float32(dynamic_range(images))
    I2 = images.reshape(k, -1)
    if order is None:
        order = np.argsort(I2, axis=0, kind="stable")
    else:
        order = order.reshape(k, -1)
    Is = np.take_along_axis(I2, order, axis=0) / D  # (k, N)
    Sf = S.astype(np.float32)
    Ss = np.stack([Sf[:, c][order] for c in range(3)], axis=-1)  # (k, N, 3)
    # determinants of consecutive triplets are shared between quadruples: compute
    # det(j, j+1, j+2) once; the two "gapped" determinants per quadruple directly
    m = k - 3
    cons = [_det3(Ss[j], Ss[j + 1], Ss[j + 2]) for j in range(k - 2)]
    err = np.empty((m, I2.shape[1]), dtype=np.float32)
    for j in range(m):
        s0, s1, s2, s3 = Ss[j], Ss[j + 1], Ss[j + 2], Ss[j + 3]
        a0 = cons[j + 1]
        a1 = -_det3(s0, s2, s3)
        a2 = _det3(s0, s1, s3)
        a3 = -cons[j]
        nrm2 = a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3
        dot = a0 * Is[j] + a1 * Is[j + 1] + a2 * Is[j + 2] + a3 * Is[j + 3]
        err[j] = np.where(nrm2 > 1e-18, dot * dot / np.maximum(nrm2, 1e-30), 0.0)
    pattern = err <= np.float32(t_nl)
    return pattern.reshape(m, H, W), err.reshape(m, H, W), order.reshape(k, H, W)


def _runs(pattern):
    """Run labels (1..r, 0 off) along axis 0 of a (m, N) bool array and run counts."""
    start = pattern.copy()
    start[1:] &= ~pattern[:-1]
    label = np.cumsum(start, axis=0, dtype=np.int16) * pattern
    return label, start.sum(axis=0)


def xnl_resolve(pattern, highlight_sorted, error=None):
    """Choose one run of Lambertian quadruples per pixel and return sorted validity.

    Rule (generalizes Section 3.3.3.2's example): a proper pattern is one run of
    consecutive ones covering quadruples f..l; sorted positions f..l+3 are valid,
    the f darkest observations are shadows and the k-4-l brightest are highlights
    (k = 8, [0 1 1 0 0] -> position 0 shadow, 6 and 7 highlights). A broken pattern
    has several runs. The brightest run is tested with the reflection mask: if any
    of the observations it covers (positions f_r..l_r+3) is a probable highlight the
    run is dropped and the test repeats on the next darker run; otherwise the run is
    kept and all darker runs are dropped. The darkest remaining run is kept without a
    test. For two runs where the brightest run is the last quadruple this is exactly
    the thesis's rule: [0 1 1 0 1] -> [0 1 1 0 0] if any of the brightest four
    observations is a highlight, else [0 0 0 0 1]. A pattern with no ones keeps the
    single quadruple of least Lambertian error (``error`` given) or, without
    ``error``, every observation.

    Parameters
    ----------
    pattern : (m, ...) bool
        m = k - 3 quadruple flags (True = Lambertian).
    highlight_sorted : (k, ...) bool
        Re flags of the observations in sorted order (darkest first).
    error : (m, ...) float, optional

    Returns
    -------
    valid_sorted : (k, ...) bool
    first, last : (...) int
        Chosen run's first and last quadruple (-1 where every observation is kept).
    """
    pattern = np.asarray(pattern, dtype=bool)
    m = pattern.shape[0]
    k = m + 3
    shp = pattern.shape[1:]
    P = pattern.reshape(m, -1)
    Hs = np.asarray(highlight_sorted, dtype=bool).reshape(k, -1)
    label, nruns = _runs(P)
    chosen = nruns.astype(np.int16)  # start with the brightest run
    decided = chosen <= 1
    pos = np.arange(k)[:, None]
    while not decided.all():
        idx = np.flatnonzero(~decided)
        lab = label[:, idx]
        c = chosen[idx]
        inrun = lab == c[None]
        f = np.argmax(inrun, axis=0)
        l = m - 1 - np.argmax(inrun[::-1], axis=0)
        cover = (pos >= f[None]) & (pos <= (l + 3)[None])
        hit = (Hs[:, idx] & cover).any(axis=0)
        c = np.where(hit, c - 1, c)
        chosen[idx] = c
        decided[idx] = ~hit | (c <= 1)
    inrun = (label == chosen[None]) & (chosen[None] >= 1)
    first = np.where(nruns > 0, np.argmax(inrun, axis=0), -1)
    last = np.where(nruns > 0, m - 1 - np.argmax(inrun[::-1], axis=0), -1)
    none = nruns == 0
    if error is not None and none.any():
        e = np.asarray(error).reshape(m, -1)
        q = np.argmin(e[:, none], axis=0)
        first[none] = q
        last[none] = q
    valid = (pos >= first[None]) & (pos <= (last + 3)[None])
    valid[:, first < 0] = True
    return valid.reshape((k,) + shp), first.reshape(shp), last.reshape(shp)


def xnl(images, S, *, t_nl, t_re=None, normals_hint=None, return_pattern=False):
    """Extended non-Lambert quadruple mask for k >= 4 images (Section 3.3.3.2).

    Per pixel the intensities are sorted darkest -> brightest; each of the k-3
    consecutive quadruples gets the Lambertian error ``(a . I / D)^2`` (|a| = 1, D the
    stack's dynamic range; module docs) and is Lambertian where the error is at most
    ``t_nl``. The pattern is turned into a validity mask by :func:`xnl_resolve`
    (leading zeros -> shadows, trailing zeros -> highlights; broken patterns are
    corrected with the reflection mask). Up to k-4 observations can be rejected.

    Parameters
    ----------
    images : (k, H, W) array_like, k >= 4
    S : (k, 3) array_like or Layout
    t_nl : float
        Lambertian error threshold (Table 5.2: 0.02 for 4 and 8 images, 0.04 for 6,
        0.01 for 12).
    t_re : float, optional
        Reflection threshold in degrees for broken patterns; default Eq. 5.1
        (:func:`t_re_default`).
    normals_hint : (H, W, 3) array_like, optional
        Normal estimate for the reflection test; default plain least squares over all
        images.
    return_pattern : bool
        Also return the (k-3, H, W) pattern before correction.

    Returns
    -------
    valid : (k, H, W) bool
        True = observation used. (valid, pattern) when ``return_pattern``.
    """
    images = as_images(images, min_count=4)
    k, H, W = images.shape
    S = _as_S(S, k)
    if t_nl is None or not float(t_nl) >= 0:
        raise PsbenchError(f"t_nl must be a number >= 0, got {t_nl!r}")
    pattern, err, order = xnl_pattern(images, S, t_nl=float(t_nl))
    P = pattern.reshape(k - 3, -1)
    # reflection flags only matter where the pattern is broken (>= 2 runs)
    _, nruns = _runs(P)
    broken = np.flatnonzero(nruns >= 2)
    Hs = np.zeros((k, H * W), dtype=bool)
    if broken.size:
        tre = t_re_default(S) if t_re is None else float(t_re)
        if normals_hint is None:
            b = kernel.ls(images.reshape(k, -1)[:, broken].reshape(k, 1, -1), S)
            n = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
        else:
            nh = np.asarray(normals_hint, dtype=np.float32)
            if nh.shape != (H, W, 3):
                raise PsbenchError(f"normals_hint must have shape {(H, W, 3)}, got {nh.shape}")
            n = nh.reshape(-1, 3)[broken].reshape(1, -1, 3)
        re = reflection_flags(n, S, tre).reshape(k, -1)
        o = order.reshape(k, -1)[:, broken]
        Hs[:, broken] = np.take_along_axis(re, o, axis=0)
    vs, _, _ = xnl_resolve(P, Hs, err.reshape(k - 3, -1))
    valid = np.empty((k, H * W), dtype=bool)
    np.put_along_axis(valid, order.reshape(k, -1), vs, axis=0)
    valid = valid.reshape(k, H, W)
    return (valid, pattern) if return_pattern else valid
