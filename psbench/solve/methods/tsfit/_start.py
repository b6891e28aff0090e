"""Start solution and observation weights of tsfit: a pluggable robust step.

The robust step is any registered method (``func(problem, options) -> Fit``), the
masked least-squares solution (``"ls"``) or a private trimmed least squares
(``"trimmed"``). ``"auto"`` is the registry's ``robust`` method when one is
registered, else ``"trimmed"``.

Its weights then get the highlights put back: a robust step drops the highlights
together with the shadows, but tsfit models the highlight, so every observation
that is not clearly darker than the model predicts gets weight 1 and the dark ones
(cast shadows, and whatever else is much darker than the model) weight 0
(:func:`put_back`). The step's weights also pick the inliers from which the noise
scale is estimated (:func:`noise_sigma`).
"""
from __future__ import annotations

import numpy as np

from . import _aux_kernel as _kx
from ._lm import _solve_spd

__all__ = ["STARTS", "resolve_start", "start_weights", "trimmed", "take", "count"]

#: start steps that are not registry methods
STARTS = ("auto", "ls", "trimmed")
#: fractions of each pixel's usable observations the trimmed start drops
#: (darkest: shadows; brightest: highlights)
TRIM_DARK, TRIM_BRIGHT = 0.25, 0.25


def take(a, sel):
    """``a[..., sel]`` (pixels last): np.take is several times faster than fancy
    indexing on the last axis of a (k, P) array."""
    return np.take(a, sel, axis=-1)


def count(w):
    """Observations of positive weight per pixel, (k, P) bool -> (P,) int32 (summing
    the bytes: 6x faster than a boolean sum over the first axis)."""
    return w.view(np.uint8).sum(axis=0, dtype=np.int32) if w.dtype == bool else \
        (w > 0).view(np.uint8).sum(axis=0, dtype=np.int32)


def resolve_start(name):
    """The start step actually used for ``name`` ("auto" resolved)."""
    if name != "auto":
        return name
    from .... import registry
    return "robust" if "robust" in registry.methods() else "trimmed"


def trimmed(I, S, valid, *, dark=TRIM_DARK, bright=TRIM_BRIGHT):
    """Per-pixel rank-trimmed least squares on gathered pixels.

    Drops the ``dark`` darkest and ``bright`` brightest fractions of each pixel's
    usable observations (``valid``; intensities divided by the light power), keeping
    at least three, and solves least squares on the rest.

    Parameters
    ----------
    I : (k, P) float32
    S : (k, 3) float
    valid : (k, P) bool

    Returns
    -------
    b : (3, P) float32
    kept : (k, P) bool
    """
    k, P = I.shape
    mu = np.linalg.norm(S, axis=1).astype(np.float32)[:, None]
    inv_mu = 1.0 / np.where(mu > 0, mu, 1)
    b = np.empty((3, P), dtype=np.float32)
    kept = np.empty((k, P), dtype=bool)
    for lo_ in range(0, P, CHUNK):  # chunks bound the sort's temporaries
        s = slice(lo_, min(P, lo_ + CHUNK))
        v = valid[:, s]
        key = np.where(v, I[:, s] * inv_mu, np.inf)  # unusable sort last
        srt = np.sort(key.T, axis=1)  # (p, k): contiguous per pixel, fast for small k
        nv = count(v)
        lo = np.floor(dark * nv).astype(np.int64)
        hi = nv - np.floor(bright * nv).astype(np.int64)
        short = (hi - lo) < 3  # keep at least three: widen towards the bright end first
        hi = np.where(short, np.minimum(nv, lo + 3), hi)
        lo = np.where(short, np.maximum(0, hi - 3), lo)
        rows = np.arange(srt.shape[0])
        t_lo = srt[rows, np.minimum(lo, k - 1)]
        t_hi = srt[rows, np.maximum(hi - 1, 0)]
        kept[:, s] = v & (key >= t_lo) & (key <= t_hi)  # ties at a bound are kept
        b[:, s] = lsq3(I[:, s], S, kept[:, s].astype(np.float32))
    return b, kept


def lsq3(I, S, w):
    """Weighted least squares rho * n per pixel, (k, P) -> (3, P) float32."""
    S = np.asarray(S, dtype=np.float64)
    outer = (S[:, :, None] * S[:, None, :]).reshape(len(S), 9).T.astype(np.float32)
    A = (outer @ w).astype(np.float64).reshape(3, 3, -1)
    r = (S.T.astype(np.float32) @ (w * I)).astype(np.float64)
    ridge = 1e-9 * (A[0, 0] + A[1, 1] + A[2, 2]) + 1e-30
    for i in range(3):
        A[i, i] += ridge
    x, ok = _solve_spd(A, r)
    x[:, ~(ok & np.isfinite(x).all(0))] = 0.0
    return x.astype(np.float32)


def start_weights(problem, name, idx, I, valid, *, want_heldout=False):
    """Run the start step ``name`` (already resolved) on the object pixels ``idx``.

    Parameters
    ----------
    problem : Problem
    name : str
    idx : (P,) int
        Flat indices of the object pixels.
    I : (k, P) float32, valid : (k, P) bool
        Their observations and the mask expression's validity.

    Returns
    -------
    b : (3, P) float32
        rho * n of the start.
    inliers : (k, P) bool
        The step's final weights >= 0.5 (all where it reports none), and ``valid``.
    heldout : tuple or None, only with ``want_heldout``
        The step's ``Fit.heldout`` (its held-out errors, used observations and
        validation error over the object pixels) when it reports them, else None.
    """
    k = I.shape[0]
    w = None
    heldout = None
    if name == "trimmed":
        b, w = trimmed(I, problem.S, valid)
    else:
        if name == "ls":
            bfull = problem.start()
        else:
            from .... import registry
            spec = registry.get("methods", name, what="start")
            fit = spec.func(problem, spec.options())
            bfull = fit.b
            heldout = getattr(fit, "heldout", None)
            if callable(heldout) and want_heldout:
                heldout = heldout()
            wf = fit.weights if fit.weights is not None else fit.valid
            if wf is not None:
                w = take(np.asarray(wf).reshape(k, -1), idx) >= 0.5
        b = np.ascontiguousarray(np.asarray(bfull, dtype=np.float32).reshape(-1, 3)[idx].T)
    inliers = valid.copy() if w is None else w & valid
    bad = ~np.isfinite(b).all(axis=0)
    if bad.any():  # a start must never poison the fit
        b[:, bad] = lsq3(I[:, bad], problem.S, valid[:, bad].astype(np.float32))
        heldout = None   # no longer the start's errors there
    return (b, inliers, heldout) if want_heldout else (b, inliers)


#: pixels per chunk of the start's per-pixel work (bounds temporaries)
CHUNK = 1 << 16
#: pixels per image used to estimate the noise scale
SIGMA_PIXELS = 65536


def noise_sigma(I, pred, w, *, lambert=False):
    """Per-image noise scale: 1.4826 x the median |I - pred| over the observations
    with weight >= 0.5 (MAD; robust to the minority the model does not explain), on
    at most ``SIGMA_PIXELS`` evenly spaced pixels.

    ``lambert=True`` (``pred`` is a Lambert prediction, without the highlight): only
    the observations below the prediction count, because a highlight only adds light
    and above the Lambert part the residual is specular reflection, not noise. A start
    that keeps the highlights among its inliers (``robust``, whose Torrance-Sparrow
    step models them) otherwise reports the specular lobe as noise (measured: a scale
    of 0.84 on noiseless mozart, 64^2, 45x16, which let every cast shadow into the fit:
    3.6 deg instead of 0.01 deg).

    Returns (k,) float32; images without such observations get the median of the
    others (0 if there are none at all).
    """
    step = max(1, I.shape[1] // SIGMA_PIXELS)
    r = pred[:, ::step] - I[:, ::step]
    inl = w[:, ::step] >= 0.5
    if lambert:
        inl &= r >= 0
    else:
        np.abs(r, out=r)
    # per image, np.median of r[i][inl[i]]: its two middle values selected in place
    mid = np.empty((r.shape[0], 4), dtype=np.int32)
    _kx.row_middles(np.ascontiguousarray(r, dtype=np.float32).view(np.int32),
                    np.ascontiguousarray(inl), mid)
    hi, lo = mid[:, 0].view(np.float32), mid[:, 1].view(np.float32)
    med = np.where(mid[:, 2] % 2 == 1, hi, (lo + hi) / np.float32(2))
    sig = np.where((mid[:, 2] > 0) & (mid[:, 3] == 0), 1.4826 * med, np.nan)
    ok = np.isfinite(sig)
    fill = float(np.median(sig[ok])) if ok.any() else 0.0
    return np.where(ok, sig, fill).astype(np.float32)


def put_back(I, valid, model, sigma, dark_ratio, dark_sigmas, *, pred=None):
    """Weights with the highlights put back, on gathered pixels.

    A usable observation is dark (a shadow the model cannot explain) when the
    model predicts more than ``dark_sigmas`` noise scales of light, and the
    observation is below ``dark_ratio`` x the prediction and more than
    ``dark_sigmas`` noise scales below it. Dark ones get weight 0, every other
    usable observation weight 1: the robust step's outliers that are bright
    (highlights) come back, and shadows it missed go. The noise margins matter:
    dropping the observations that noise happened to push down (e.g. the negative
    noise of a self-shadowed observation) would bias the fit.

    Parameters
    ----------
    I : (k, P) float32
        Observations.
    valid : (k, P) bool
        The mask expression's validity (never overridden).
    model : tuple
        ``(L, n, rd, rs, m)``: the lights (:class:`_lm.Lights`), unit normals
        (3, P), and per-pixel rho_d, rho_s, m (P,) of the prediction (clamped at 0
        in self shadow); ``rs=None``: the Lambert prediction rho_d (s_i . n).
    sigma : (k,) float32
        Per-image noise scale (:func:`noise_sigma`).
    pred : (k, P) float32, optional
        The Lambert + Torrance-Sparrow prediction of ``model`` when the caller has
        it (:func:`_lm.predict`: the same float32 values), so that it is not
        evaluated twice.

    Returns
    -------
    (k, P) bool
        The weights (1 = True).
    """
    L, n, rd, rs, m = model
    lobe = rs is not None
    f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
    rs = f32(rs) if lobe else np.zeros(1, np.float32)
    m = f32(m) if lobe else np.zeros(1, np.float32)
    margin = f32(np.float32(dark_sigmas) * np.asarray(sigma, dtype=np.float32))
    w = np.empty(I.shape, dtype=bool)
    if pred is not None:
        _kx.dark_weights_pred(f32(pred), f32(I), np.ascontiguousarray(valid, dtype=bool),
                              margin, np.float32(dark_ratio), w)
        return w
    _kx.dark_weights(L.table, f32(n), f32(rd), rs, m, lobe, f32(I),
                     np.ascontiguousarray(valid, dtype=bool), margin,
                     np.float32(dark_ratio), w)
    return w


def lambert_pred(b, S):
    """Clamped Lambert prediction max(s_i . b, 0), (k, P) float32."""
    pred = np.asarray(S, dtype=np.float32) @ b
    return np.maximum(pred, 0.0, out=pred)


def unit(b):
    """(3, P) -> unit normals (0, 0, 1 where b is 0) (3, P) and albedo (P,)."""
    rho = np.sqrt((b * b).sum(0))
    ok = rho > 1e-6
    n = np.where(ok, b / np.where(ok, rho, 1.0), np.float32([[0], [0], [1]]))
    return n.astype(np.float32), np.where(ok, rho, 0.0).astype(np.float32)
