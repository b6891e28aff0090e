"""Areal comparison of breech-face impressions: band-pass, registration, CCFmax.

The forensic question is whether two reconstructed cases were fired by the same gun.
psbench answers it the way the field's topography comparisons do (NIST: Song &
Vorburger; Song 2013; Tong, Song & Chu 2015; Song et al. 2018):

1. **Band-pass** the heights with a Gaussian filter: the long-wavelength cut-off
   removes form and waviness (the case's bulge, tilt, seating), the short one removes
   noise. Breech-face comparisons use cut-offs of **16 µm and 250 µm** (Song et al.,
   "Estimating error rates for firearm evidence identifications in forensic science",
   Forensic Sci. Int. 284 (2018) 15-32, and the reference implementation of the
   Congruent Matching Cells method, the R package cmcR, Zemmels, Hofmann & VanderPlas,
   whose default pre-processing follows them). The filter is the ISO 16610-61 areal
   Gaussian (weighting ``exp(-pi (r / (alpha lambda))^2)``, alpha = sqrt(ln 2 / pi), 50 %
   transmission at the cut-off, i.e. sigma = lambda sqrt(ln 2) / (pi sqrt 2) =
   0.1874 lambda), applied as a zero-order Gaussian regression filter on the valid
   region only (normalised convolution), so missing data and the region's border do not
   bleed into the marks.
2. **Register** the two filtered maps over rotation and translation: an exhaustive
   rotation search at a coarse level of a Gaussian pyramid with a masked normalised
   cross-correlation over all translations computed by FFT (Padfield, "Masked object
   registration in the Fourier domain", IEEE TIP 21 (2012) 2706-2718), then refinement
   of the best candidates level by level to full resolution with sub-pixel translation.
3. **CCFmax**: the maximum of the normalised cross-correlation (Pearson correlation of
   the overlapping valid pixels), 1 for identical topographies.

A sister pair should score high, a pair from different guns low; the separation of the
two populations is what :mod:`psbench.forensic.pipeline` reports.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import scipy.fft as sfft

from .._shared.checks import PsbenchError, as_mask
from .cartridge import check_pixel_size

__all__ = ["SHORT_CUTOFF", "LONG_CUTOFF", "cutoff_sigma", "bandpass", "Match", "register",
           "compare", "ncc"]

#: short-wavelength cut-off (µm) of breech-face comparisons
SHORT_CUTOFF = 16.0
#: long-wavelength cut-off (µm) of breech-face comparisons
LONG_CUTOFF = 250.0
#: default short cut-off in pixels when 16 µm is finer than that (coarse images):
#: wavelengths of 2-3 pixels do not survive resampling at another rotation (two
#: cases are sampled on differently oriented grids), so they would only add noise
SHORT_FLOOR = 3.0
_SIGMA_PER_CUTOFF = math.sqrt(math.log(2.0)) / (math.pi * math.sqrt(2.0))   # 0.18739
_PRUNE_SIDE = 160   # window side (pixels) from which only the best candidate is refined


def cutoff_sigma(cutoff, pixel_size):
    """Standard deviation (pixels) of the Gaussian with 50 % transmission at ``cutoff`` µm."""
    return cutoff * _SIGMA_PER_CUTOFF / pixel_size


def _smooth(values, weights, sigma):
    """Zero-order Gaussian regression: G*(v w) / G*(w) (NaN where G*w ~ 0)."""
    num = cv2.GaussianBlur(values * weights, (0, 0), sigmaX=sigma, borderType=cv2.BORDER_CONSTANT)
    den = cv2.GaussianBlur(weights, (0, 0), sigmaX=sigma, borderType=cv2.BORDER_CONSTANT)
    with np.errstate(invalid="ignore", divide="ignore"):
        return num / den


def _cutoffs(shape, pixel_size, short, long):
    nyq = 2.0 * pixel_size
    extent = min(shape) * pixel_size
    if short is None:
        short = max(SHORT_CUTOFF, SHORT_FLOOR * pixel_size)
    else:
        short = float(short)
        if not math.isfinite(short) or short < nyq:
            raise PsbenchError(f"short={short!r} um is below the image's band: the Nyquist "
                               f"wavelength is 2 x pixel_size = {nyq:.3g} um")
    long = float(long)
    if not math.isfinite(long) or long <= short:
        raise PsbenchError(f"long={long!r} um must exceed the short cut-off ({short:.3g} um)")
    if long > extent:
        raise PsbenchError(f"long={long:g} um is beyond the image's band: the image spans "
                           f"only {extent:.0f} um")
    return short, long


def bandpass(height, valid=None, *, pixel_size, short=None, long=LONG_CUTOFF):
    """Gaussian band-pass of a height map (zero-order regression on ``valid``).

    Parameters
    ----------
    height : (H, W) array_like
        Heights in µm.
    valid : (H, W) bool, optional
        Pixels that carry data (e.g. the breech-face region); default all.
    pixel_size : float
        µm per pixel.
    short : float, optional
        Short-wavelength cut-off, µm; default :data:`SHORT_CUTOFF` (16 µm), or 3 pixels
        (:data:`SHORT_FLOOR`) on images too coarse for 16 µm. Must be >= 2 x pixel_size
        (the Nyquist wavelength).
    long : float, default 250
        Long-wavelength cut-off, µm; > short and at most the image's extent.

    Returns
    -------
    (H, W) float32
        Filtered heights, 0 outside ``valid``.
    """
    ps = check_pixel_size(pixel_size)
    z = np.asarray(height, np.float32)
    if z.ndim != 2:
        raise PsbenchError(f"height must have shape (H, W), got {z.shape}")
    m = as_mask(valid, z.shape, "valid") & np.isfinite(z)
    short, long = _cutoffs(z.shape, ps, short, long)
    w = m.astype(np.float32)
    z = np.where(m, z, 0).astype(np.float32)
    lo = _smooth(z, w, cutoff_sigma(short, ps))
    form = _smooth(z, w, cutoff_sigma(long, ps))
    out = np.where(m, lo - form, 0.0)
    return np.nan_to_num(out, copy=False).astype(np.float32)


@dataclass(frozen=True)
class Match:
    """Result of :func:`register`.

    Attributes
    ----------
    ccf : float
        CCFmax: Pearson correlation of the overlapping valid pixels at the best pose.
    angle : float
        Degrees: rotating ``b`` counter-clockwise (as displayed, y up) by this angle,
        then translating, lays it on ``a``.
    matrix : (2, 3) float64
        Affine map of ``b``'s pixel coordinates (column, row) onto ``a``'s.
    overlap : float
        Overlapping valid pixels as a fraction of the smaller valid region.
    """

    ccf: float
    angle: float
    matrix: np.ndarray
    overlap: float


def ncc(a, b, valid_a=None, valid_b=None):
    """Pearson correlation of two aligned maps over their common valid pixels."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    m = as_mask(valid_a, a.shape, "valid_a") & as_mask(valid_b, b.shape, "valid_b")
    if m.sum() < 3:
        return float("nan")
    x, y = a[m], b[m]
    x, y = x - x.mean(), y - y.mean()
    d = math.sqrt(float((x * x).sum() * (y * y).sum()))
    return float((x * y).sum() / d) if d > 0 else float("nan")


# ----------------------------------------------------------------------------- registration
def _window(z, m, side):
    """A (side, side) window centred on the valid region's centroid; returns (z, m, centre)."""
    rr, cc = np.nonzero(m)
    cy, cx = float(rr.mean()), float(cc.mean())
    M = np.float64([[1, 0, side / 2 - 0.5 - cx], [0, 1, side / 2 - 0.5 - cy]])
    zw = cv2.warpAffine(z * m, M, (side, side), flags=cv2.INTER_NEAREST)
    mw = cv2.warpAffine(m.astype(np.uint8), M, (side, side), flags=cv2.INTER_NEAREST) > 0
    return zw.astype(np.float32), mw, (cx, cy)


def _down(z, m):
    """One Gaussian pyramid level of masked data."""
    w = m.astype(np.float32)
    zs = cv2.pyrDown(z * w)
    ws = cv2.pyrDown(w)
    keep = ws > 0.75
    with np.errstate(invalid="ignore", divide="ignore"):
        out = np.where(keep, zs / ws, 0.0).astype(np.float32)
    return out, keep


class _Ref:
    """FFTs of the reference window for masked NCC against many moving windows."""

    def __init__(self, a, ma, shape):
        self.shape = shape
        wa = ma.astype(np.float32)
        a = a * wa
        self.fa, self.fa2, self.fma = np.conj(sfft.rfft2(np.stack([a, a * a, wa]), s=shape,
                                                         workers=-1))
        self.n = float(wa.sum())

    def map(self, b, mb, min_count):
        """NCC over all cyclic shifts s (a(x) vs b(x + s)); -inf where overlap is small."""
        wb = mb.astype(np.float32)
        b = b * wb
        # one batched call per direction: the transforms of a stack are those of its
        # slices, and the batch spreads over the workers
        fb, fb2, fmb = sfft.rfft2(np.stack([b, b * b, wb]), s=self.shape, workers=-1)
        prod = np.stack([self.fma * fmb, self.fa * fb, self.fa * fmb, self.fma * fb,
                         self.fa2 * fmb, self.fma * fb2])
        n, sab, sa, sb, saa, sbb = sfft.irfft2(prod, s=self.shape, workers=-1)
        n = np.rint(n)
        with np.errstate(invalid="ignore", divide="ignore"):
            num = sab - sa * sb / n
            den = (saa - sa * sa / n) * (sbb - sb * sb / n)
            r = num / np.sqrt(np.maximum(den, 1e-30))
        r[(n < min_count) | ~np.isfinite(r)] = -np.inf
        return r


def _rot(z, m, angle, shift=(0.0, 0.0), interp=cv2.INTER_LINEAR):
    """Rotate a window counter-clockwise by ``angle`` degrees about its centre, then shift
    by (dx, dy) pixels (columns, rows)."""
    side = z.shape[0]
    M = cv2.getRotationMatrix2D((side / 2 - 0.5, side / 2 - 0.5), angle, 1.0)
    M[:, 2] += shift
    zr = cv2.warpAffine(z, M, (side, side), flags=interp)
    mr = cv2.warpAffine(m.astype(np.float32), M, (side, side), flags=cv2.INTER_LINEAR) > 0.999
    return zr, mr, M


def _peak(r, radius=None):
    """(value, dy, dx) of the maximum of a cyclic NCC map (shifts in [-n/2, n/2)),
    optionally within ``radius`` of zero shift; sub-pixel by parabolic interpolation."""
    H, W = r.shape
    if radius is not None:
        rr = np.full_like(r, -np.inf)
        k = int(radius)
        idx_y = np.r_[0:k + 1, H - k:H]
        idx_x = np.r_[0:k + 1, W - k:W]
        rr[np.ix_(idx_y, idx_x)] = r[np.ix_(idx_y, idx_x)]
        r = rr
    i = int(np.argmax(r))
    y, x = divmod(i, W)
    v = float(r[y, x])

    def sub(c, minus, plus):
        # a neighbour outside the search radius (or an empty map) is -inf: no refinement
        if not (np.isfinite(c) and np.isfinite(minus) and np.isfinite(plus)):
            return 0.0
        d = minus - 2 * c + plus
        if d >= 0:
            return 0.0
        return float(np.clip(0.5 * (minus - plus) / d, -0.5, 0.5))

    dy = sub(v, r[(y - 1) % H, x], r[(y + 1) % H, x])
    dx = sub(v, r[y, (x - 1) % W], r[y, (x + 1) % W])
    sy = y - H if y >= H // 2 else y
    sx = x - W if x >= W // 2 else x
    return v, sy + dy, sx + dx


def register(a, b, valid_a=None, valid_b=None, *, min_overlap=0.5, coarse=96, candidates=3,
             angles=None):
    """Register ``b`` onto ``a`` over rotation and translation; CCFmax at the best pose.

    Parameters
    ----------
    a, b : (H, W) array_like
        Band-passed heights (any two shapes).
    valid_a, valid_b : (H, W) bool, optional
        Their valid regions (default all).
    min_overlap : float, default 0.5
        Poses overlapping less than this fraction of the smaller valid region are not
        considered (a tiny overlap can correlate by chance).
    coarse : int, default 96
        The rotation search runs on the pyramid level whose window is at most this many
        pixels; its angle step is ~1.5 pixels of arc at the window's edge.
    candidates : int, default 3
        Best coarse angles (at least 6 steps apart) refined until the pyramid level's
        window is 160 pixels wide; the best of them is refined to full resolution.
    angles : (float, float), optional
        Range of rotation (degrees) to search; default the full circle.

    Returns
    -------
    Match
    """
    a = np.asarray(a, np.float32)
    b = np.asarray(b, np.float32)
    ma = as_mask(valid_a, a.shape, "valid_a") & np.isfinite(a)
    mb = as_mask(valid_b, b.shape, "valid_b") & np.isfinite(b)
    if ma.sum() < 16 or mb.sum() < 16:
        raise PsbenchError("valid_a and valid_b must each hold at least 16 pixels")
    if not 0 < float(min_overlap) <= 1:
        raise PsbenchError(f"min_overlap must be in (0, 1], got {min_overlap!r}")
    ext = lambda m: max(np.ptp(np.nonzero(m)[0]), np.ptp(np.nonzero(m)[1])) + 1  # noqa: E731
    side = int(sfft.next_fast_len(int(1.05 * max(ext(ma), ext(mb))) + 4))
    side += side % 2
    aw, maw, ca = _window(np.where(ma, a, 0), ma, side)
    bw, mbw, cb = _window(np.where(mb, b, 0), mb, side)
    pyr = [(aw, maw, bw, mbw)]
    while pyr[-1][0].shape[0] > coarse and pyr[-1][0].shape[0] >= 32:
        A, MA, B, MB = pyr[-1]
        pyr.append(_down(A, MA) + _down(B, MB))
    smaller = float(min(ma.sum(), mb.sum()))

    def search(level, angle_list, centre=None, radius=None):
        A, MA, B, MB = pyr[level]
        scale = 2.0 ** level
        n = A.shape[0]
        pad = n if radius is None else int(radius) + 2
        shape = (sfft.next_fast_len(n + pad), sfft.next_fast_len(n + pad))
        ref = _Ref(A, MA, shape)
        min_count = min_overlap * smaller / scale ** 2
        out = []
        for ang in angle_list:
            # translation applied after the rotation (level pixels); the map's peak s
            # (a(x) ~ Br(x + s)) corrects it by -s
            shift = (0.0, 0.0) if centre is None else (centre[0] / scale, centre[1] / scale)
            Br, MBr, _ = _rot(B, MB, ang, shift)
            v, sy, sx = _peak(ref.map(Br, MBr, min_count), radius)
            tx = (shift[0] - sx) * scale
            ty = (shift[1] - sy) * scale
            out.append((v, float(ang), tx, ty))
        return out

    top = len(pyr) - 1
    r_top = pyr[top][0].shape[0] / 2.0
    step = math.degrees(1.5 / r_top)
    if angles is None:
        lo, hi = 0.0, 360.0
    else:
        try:
            lo, hi = (float(v) for v in angles)
        except (TypeError, ValueError):
            raise PsbenchError(f"angles must be a (low, high) pair of degrees, "
                               f"got {angles!r}") from None
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise PsbenchError(f"angles must be a (low, high) pair of degrees, low < high, "
                               f"got {angles!r}")
    grid = np.arange(lo, hi, step)
    res = search(top, grid)
    order = sorted(range(len(res)), key=lambda i: -res[i][0])
    picks = []
    for i in order:
        if not np.isfinite(res[i][0]):
            break
        if all(min(abs(res[i][1] - p[1]) % 360, 360 - abs(res[i][1] - p[1]) % 360) > 6 * step
               for p in picks):
            picks.append(res[i])
        if len(picks) >= candidates:
            break
    if not picks:
        return Match(float("nan"), float("nan"), np.full((2, 3), np.nan), 0.0)
    # refine every candidate level by level; once the windows are large enough to
    # tell them apart (_PRUNE_SIDE), only the best goes on to the costly fine levels
    states, st = list(picks), step
    for level in range(top - 1, -1, -1):
        r_l = pyr[level][0].shape[0] / 2.0
        new = math.degrees(1.0 / r_l)
        refined = []
        for v, ang, tx, ty in states:
            cand = search(level, ang + np.arange(-st, st + 1e-9, new), centre=(tx, ty), radius=3)
            v, ang, tx, ty = max(cand, key=lambda c: c[0])
            # parabolic angle refinement through the best and its neighbours
            vals = {round(c[1], 9): c[0] for c in cand}
            vm, vp = vals.get(round(ang - new, 9)), vals.get(round(ang + new, 9))
            if vm is not None and vp is not None and np.isfinite(vm) and np.isfinite(vp):
                d = vm - 2 * v + vp
                if d < 0:
                    ang += float(np.clip(0.5 * (vm - vp) / d, -0.5, 0.5)) * new
            refined.append((v, ang, tx, ty))
        states = refined
        if len(states) > 1 and 2 * r_l >= _PRUNE_SIDE:
            states = [max(states, key=lambda c: c[0] if np.isfinite(c[0]) else -np.inf)]
        st = new
    best = None
    for v, ang, tx, ty in states:
        Br, MBr, M = _rot(pyr[0][2], pyr[0][3], ang, (tx, ty), cv2.INTER_CUBIC)
        val = ncc(pyr[0][0], Br, pyr[0][1], MBr)
        if best is None or (np.isfinite(val) and val > best[0]):
            best = (val, ang, M, float((pyr[0][1] & MBr).sum()) / smaller)
    val, ang, M, ov = best
    # compose: b pixel -> b window -> rotated/shifted window -> a window -> a pixel
    Wb = np.float64([[1, 0, side / 2 - 0.5 - cb[0]], [0, 1, side / 2 - 0.5 - cb[1]], [0, 0, 1]])
    Wa_inv = np.float64([[1, 0, ca[0] - side / 2 + 0.5], [0, 1, ca[1] - side / 2 + 0.5], [0, 0, 1]])
    full = Wa_inv @ np.vstack([M, [0, 0, 1]]) @ Wb
    return Match(float(val), float(ang % 360.0), full[:2], ov)


def compare(height_a, height_b, valid_a=None, valid_b=None, *, pixel_size, short=None,
            long=LONG_CUTOFF, **register_options):
    """Band-pass two height maps (µm) and register them: :func:`bandpass` then
    :func:`register`. Returns a :class:`Match` (``.ccf`` is CCFmax)."""
    fa = bandpass(height_a, valid_a, pixel_size=pixel_size, short=short, long=long)
    fb = bandpass(height_b, valid_b, pixel_size=pixel_size, short=short, long=long)
    return register(fa, fb, valid_a, valid_b, **register_options)
