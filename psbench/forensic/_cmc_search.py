"""Registration of every CMC cell on the target: batched FFT correlation per angle.

:func:`register_cells` is the search behind :func:`psbench.forensic.cmc`: for each cell
of the reference, the rotation (of the given angles) and translation (within the target
region) of best Pearson correlation. ``coarse = 1`` searches every angle and translation
at full resolution; ``coarse = f > 1`` searches them on f x f block means (f^2 fewer
pixels per transform), then, at full resolution, re-registers each cell at its best
coarse angle and the ``refine`` neighbouring angles on each side, within ``2 f``
pixels of f times the coarse translation found at that angle.

Per angle the target is rotated once (all cells share it); the correlation of every
cell over every translation is one batch of real FFTs (values, squares and mask of the
target regions forward; correlation, target energy and overlap under each cell
inverse); the Pearson correlation of the common valid pixels is then taken at each
cell's best translation. No loop over cells or pixels.
"""
from __future__ import annotations

import cv2
import numpy as np
import scipy.fft as sfft
from numpy.lib.stride_tricks import sliding_window_view

__all__ = ["rotated", "patches", "pearson", "register_cells", "SEARCH_REVISION"]

#: bump when the search's results change: study caches are keyed on it
SEARCH_REVISION = 2

def stacked(z, m):
    """Values and mask as one (H, W, 2) float32 image: one warp moves both."""
    return np.ascontiguousarray(np.dstack([z, m]).astype(np.float32))


def _matrix(theta, cb, ca, shift=(0.0, 0.0)):
    """(2, 3) affine: rotation by ``theta`` about ``cb``, ``cb`` put on ``ca`` + shift."""
    M = cv2.getRotationMatrix2D((float(cb[0]), float(cb[1])), float(theta), 1.0)
    M[:, 2] += (ca[0] - cb[0] + shift[0], ca[1] - cb[1] + shift[1])
    return M


def rotated(zm, theta, cb, ca, shape, shift=(0.0, 0.0)):
    """Target :func:`stacked` ``zm`` rotated by ``theta`` about ``cb``, ``cb`` put on
    ``ca`` (+ shift), in a frame of ``shape``; values 0 and mask False where there is
    no data. Returns z, mask, M (the (2, 3) affine)."""
    M = _matrix(theta, cb, ca, shift)
    size = (shape[1], shape[0])
    out = cv2.warpAffine(zm, M, size, flags=cv2.INTER_LINEAR, borderValue=(0.0, 0.0))
    mr = out[..., 1] > 0.999   # only pixels whose four neighbours all carry data
    return np.where(mr, out[..., 0], 0.0).astype(np.float32), mr, M


def pearson(x, y, m, min_count):
    """Row-wise Pearson correlation of (n, P) arrays over mask ``m`` (None: all); NaN if
    fewer than ``min_count`` pixels."""
    if m is None:
        m = np.ones(x.shape, bool)
    cnt = m.sum(1)
    min_count = np.broadcast_to(np.asarray(min_count, float).reshape(-1), cnt.shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        mx = (x * m).sum(1) / cnt
        my = (y * m).sum(1) / cnt
        xc = (x - mx[:, None]) * m
        yc = (y - my[:, None]) * m
        r = (xc * yc).sum(1) / np.sqrt((xc * xc).sum(1) * (yc * yc).sum(1))
    r[(cnt < min_count) | ~np.isfinite(r)] = np.nan
    return r


def downsample(z, m, f):
    """f x f block means; a block is valid when all its pixels are."""
    H, W = (s // f * f for s in z.shape)
    zz = np.where(m, z, 0)[:H, :W].reshape(H // f, f, W // f, f).mean((1, 3))
    mm = m[:H, :W].reshape(H // f, f, W // f, f).all((1, 3))
    return np.where(mm, zz, 0).astype(np.float32), mm


class Cells:
    """The reference's cells in a padded frame: zero-mean values, masks, spectra."""

    def __init__(self, A, MA, tops, lefts, ch, cw, floor):
        self.tops, self.lefts, self.shape = np.asarray(tops), np.asarray(lefts), (ch, cw)
        cm = sliding_window_view(MA, (ch, cw))[self.tops, self.lefts]
        ca = sliding_window_view(A, (ch, cw))[self.tops, self.lefts]
        cnt = cm.sum((1, 2))
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = (ca * cm).sum((1, 2)) / cnt
        self.ca = np.where(cm, ca - np.nan_to_num(mean)[:, None, None], 0).astype(np.float32)
        self.cm, self.cnt = cm, cnt
        self.energy = (self.ca * self.ca).sum((1, 2))
        # too small an overlap correlates by chance: at least half the cell's data
        self.need = np.maximum(float(floor), 0.5 * cnt) - 0.5
        self._spectra = {}

    def spectra(self, fh, fw, workers=1):
        if (fh, fw) not in self._spectra:
            ch, cw = self.shape
            pad = np.zeros((len(self.ca), fh, fw), np.float32)
            pad[:, :ch, :cw] = self.ca
            FA = np.conj(sfft.rfft2(pad, workers=workers))
            pad[:, :ch, :cw] = self.cm
            FM = np.conj(sfft.rfft2(pad, workers=workers))
            self._spectra[(fh, fw)] = FA, FM
        return self._spectra[(fh, fw)]


def patches(zm, theta, cb, ca, rows, cols, shape):
    """Regions of ``shape`` at (``rows``, ``cols``) of the target rotated as
    :func:`rotated` would rotate it into its whole frame, warped one region at a time:
    the refinement needs a few small regions per angle, not the whole frame."""
    M = _matrix(theta, cb, ca)
    out = np.empty((len(rows),) + tuple(shape) + (2,), np.float32)
    size = (shape[1], shape[0])
    for i, (r, c) in enumerate(zip(rows, cols)):     # a few regions per angle
        Mi = M.copy()
        Mi[:, 2] -= (c, r)
        out[i] = cv2.warpAffine(zm, Mi, size, flags=cv2.INTER_LINEAR, borderValue=(0.0, 0.0))
    mr = out[..., 1] > 0.999
    return np.where(mr, out[..., 0], 0.0).astype(np.float32), mr


def search(cells, idx, rb, rm, cy, cx, hy, hx, limit, workers=1):
    """Best translation of cells ``idx`` within (cy +- hy, cx +- hx) on the rotated target.

    ``rb, rm`` (n, ch + 2 hy, cw + 2 hx) are the target's values and mask in each cell's
    region, whose corner is at (top + cy - hy, left + cx - hx) of the rotated target.
    ``cy, cx`` (per cell) and the result are shifts of the cell in target pixels (the
    cell at ``top + s`` on it); shifts beyond ``limit`` (|sy|, |sx|) are not taken.
    Returns Pearson r (NaN if none), sy, sx and the overlap (fraction of each cell's
    valid pixels that fall on the target's there).
    """
    ch, cw = cells.shape
    th, tw = ch + 2 * hy, cw + 2 * hx
    fh, fw = sfft.next_fast_len(th, real=True), sfft.next_fast_len(tw, real=True)
    FA, FM = cells.spectra(fh, fw, workers)
    if len(idx) != len(FA):          # the refinement: some cells only
        FA, FM = FA[idx], FM[idx]
    n = len(idx)
    pad = np.zeros((n, fh, fw), np.float32)
    pad[:, :th, :tw] = rb
    FB = sfft.rfft2(pad, workers=workers)
    np.multiply(rb, rb, out=pad[:, :th, :tw])
    FB2 = sfft.rfft2(pad, workers=workers)
    pad[:, :th, :tw] = rm
    FMB = sfft.rfft2(pad, workers=workers)
    del pad
    # index t: cell pixel u against region pixel u + t, i.e. shift s = c + t - h
    sl = (slice(None), slice(0, 2 * hy + 1), slice(0, 2 * hx + 1))
    num = sfft.irfft2(FA * FB, s=(fh, fw), workers=workers)[sl]
    den = sfft.irfft2(FM * FB2, s=(fh, fw), workers=workers)[sl]
    over = sfft.irfft2(FM * FMB, s=(fh, fw), workers=workers)[sl]
    with np.errstate(invalid="ignore", divide="ignore"):
        score = num / np.sqrt(np.maximum(den, 1e-12) * cells.energy[idx, None, None])
    sy_all = cy[:, None] + np.arange(2 * hy + 1)[None, :] - hy
    sx_all = cx[:, None] + np.arange(2 * hx + 1)[None, :] - hx
    bad = (~np.isfinite(score) | (over < cells.need[idx, None, None])
           | (np.abs(sy_all) > limit[0])[:, :, None] | (np.abs(sx_all) > limit[1])[:, None, :])
    score[bad] = -np.inf
    flat = score.reshape(n, -1).argmax(1)
    iy, ix = np.divmod(flat, 2 * hx + 1)
    sy, sx = cy + iy - hy, cx + ix - hx
    at = np.arange(n)
    pb = sliding_window_view(rb, (ch, cw), axis=(1, 2))[at, iy, ix]
    pm = sliding_window_view(rm, (ch, cw), axis=(1, 2))[at, iy, ix]
    both = (cells.cm[idx] & pm).reshape(n, -1)
    r = pearson(cells.ca[idx].reshape(n, -1), pb.reshape(n, -1), both, cells.need[idx])
    r[~np.isfinite(score.reshape(n, -1)[at, flat])] = np.nan
    return r, sy, sx, both.sum(1) / np.maximum(cells.cnt[idx], 1)


def _whole(p, theta, workers):
    """Every cell searched over its whole region on the target rotated by ``theta``."""
    cells = p["cells"]
    n = len(cells.ca)
    hy, hx = p["half"]
    ch, cw = cells.shape
    B, MB, _ = rotated(p["zmb"], theta, p["cb"], p["ca"], p["frame"])
    rows, cols = cells.tops - hy, cells.lefts - hx
    rb = sliding_window_view(B, (ch + 2 * hy, cw + 2 * hx))[rows, cols]
    rm = sliding_window_view(MB, (ch + 2 * hy, cw + 2 * hx))[rows, cols]
    zeros = np.zeros(n, int)
    return np.stack(search(cells, np.arange(n), rb, rm, zeros, zeros, hy, hx, p["half"],
                           workers), 1)


def register_cells(problem, angles, *, coarse=2, refine=1, workers=1):
    """Best (ccf, sy, sx, angle index) of every cell over ``angles``.

    ``problem(f)`` returns the problem at block size f (1 = full resolution): a dict of
    ``cells`` (:class:`Cells`), ``zmb`` (target, :func:`stacked`), ``cb, ca`` (rotation
    centre on the target, its place in the frame), ``frame`` (shape), ``half`` (the
    search's half-widths in rows, cols). ``workers``: threads of the transforms.

    Returns
    -------
    ccf, sy, sx, overlap : (n,) arrays
        Pearson correlation (NaN: no valid pose), shift and overlap (fraction of the
        cell's valid pixels on the target's) of each cell at its best pose.
    k : (n,) int
        Index of its best angle.
    """
    K = len(angles)
    f = int(coarse)
    pc = problem(f)
    rough = np.stack([_whole(pc, theta, workers) for theta in angles])
    if f <= 1:
        return _pick(rough)
    n = rough.shape[1]
    kc = _pick(rough)[-1]
    p = problem(1)
    cells = p["cells"]
    ch, cw = cells.shape
    best = np.full((K, n, 4), np.nan)
    win = 2 * f
    for k, theta in enumerate(angles):
        idx = np.flatnonzero((np.abs(kc - k) <= refine) & np.isfinite(rough[k, :, 0]))
        if not len(idx):
            continue
        cy = (f * rough[k, idx, 1]).astype(int)
        cx = (f * rough[k, idx, 2]).astype(int)
        rb, rm = patches(p["zmb"], theta, p["cb"], p["ca"], cells.tops[idx] + cy - win,
                         cells.lefts[idx] + cx - win, (ch + 2 * win, cw + 2 * win))
        best[k, idx] = np.stack(search(cells, idx, rb, rm, cy, cx, win, win, p["half"],
                                       workers), 1)
    return _pick(best)


def _pick(best):
    score = np.where(np.isfinite(best[..., 0]), best[..., 0], -np.inf)
    k = score.argmax(0)
    sel = best[k, np.arange(best.shape[1])]
    return sel[:, 0], sel[:, 1], sel[:, 2], sel[:, 3], k
