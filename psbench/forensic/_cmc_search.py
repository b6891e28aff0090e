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

__all__ = ["rotated", "pearson", "register_cells"]

#: threads of the transforms (the machine's cores)
WORKERS = -1


def stacked(z, m):
    """Values and mask as one (H, W, 2) float32 image: one warp moves both."""
    return np.ascontiguousarray(np.dstack([z, m]).astype(np.float32))


def rotated(zm, theta, cb, ca, shape, shift=(0.0, 0.0)):
    """Target :func:`stacked` ``zm`` rotated by ``theta`` about ``cb``, ``cb`` put on
    ``ca`` (+ shift), in a frame of ``shape``; values 0 and mask False where there is
    no data. Returns z, mask, M (the (2, 3) affine)."""
    M = cv2.getRotationMatrix2D((float(cb[0]), float(cb[1])), float(theta), 1.0)
    M[:, 2] += (ca[0] - cb[0] + shift[0], ca[1] - cb[1] + shift[1])
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

    def spectra(self, fh, fw):
        if (fh, fw) not in self._spectra:
            ch, cw = self.shape
            pad = np.zeros((len(self.ca), fh, fw), np.float32)
            pad[:, :ch, :cw] = self.ca
            FA = np.conj(sfft.rfft2(pad, workers=WORKERS))
            pad[:, :ch, :cw] = self.cm
            FM = np.conj(sfft.rfft2(pad, workers=WORKERS))
            self._spectra[(fh, fw)] = FA, FM
        return self._spectra[(fh, fw)]


def search(cells, idx, B, MB, cy, cx, hy, hx, limit):
    """Best translation of cells ``idx`` within (cy +- hy, cx +- hx) on the rotated target.

    ``cy, cx`` (per cell) and the result are shifts of the cell in target pixels (the
    cell at ``top + s`` on B); shifts beyond ``limit`` (|sy|, |sx|) are not taken.
    Returns Pearson r (NaN if none), sy, sx and the overlap (fraction of each cell's
    valid pixels that fall on the target's there).
    """
    ch, cw = cells.shape
    th, tw = ch + 2 * hy, cw + 2 * hx
    fh, fw = sfft.next_fast_len(th, real=True), sfft.next_fast_len(tw, real=True)
    FA, FM = cells.spectra(fh, fw)
    FA, FM = FA[idx], FM[idx]
    rows = cells.tops[idx] + cy - hy
    cols = cells.lefts[idx] + cx - hx
    rb = sliding_window_view(B, (th, tw))[rows, cols]
    rm = sliding_window_view(MB, (th, tw))[rows, cols]
    n = len(idx)
    pad = np.zeros((n, fh, fw), np.float32)
    pad[:, :th, :tw] = rb
    FB = sfft.rfft2(pad, workers=WORKERS)
    pad[:, :th, :tw] = rb * rb
    FB2 = sfft.rfft2(pad, workers=WORKERS)
    pad[:, :th, :tw] = rm
    FMB = sfft.rfft2(pad, workers=WORKERS)
    del pad
    # index t: cell pixel u against region pixel u + t, i.e. shift s = c + t - h
    sl = (slice(None), slice(0, 2 * hy + 1), slice(0, 2 * hx + 1))
    num = sfft.irfft2(FA * FB, s=(fh, fw), workers=WORKERS)[sl]
    den = sfft.irfft2(FM * FB2, s=(fh, fw), workers=WORKERS)[sl]
    over = sfft.irfft2(FM * FMB, s=(fh, fw), workers=WORKERS)[sl]
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
    pb = sliding_window_view(B, (ch, cw))[cells.tops[idx] + sy, cells.lefts[idx] + sx]
    pm = sliding_window_view(MB, (ch, cw))[cells.tops[idx] + sy, cells.lefts[idx] + sx]
    both = (cells.cm[idx] & pm).reshape(n, -1)
    r = pearson(cells.ca[idx].reshape(n, -1), pb.reshape(n, -1), both, cells.need[idx])
    r[~np.isfinite(score.reshape(n, -1)[np.arange(n), flat])] = np.nan
    return r, sy, sx, both.sum(1) / np.maximum(cells.cnt[idx], 1)


def register_cells(problem, angles, *, coarse=2, refine=1):
    """Best (ccf, sy, sx, angle index) of every cell over ``angles``.

    ``problem(f)`` returns the problem at block size f (1 = full resolution): a dict of
    ``cells`` (:class:`Cells`), ``zb, mb`` (target), ``cb, ca`` (rotation centre on the
    target, its place in the frame), ``frame`` (shape), ``half`` (the search's
    half-widths in rows, cols).

    Returns
    -------
    ccf, sy, sx, overlap : (n,) arrays
        Pearson correlation (NaN: no valid pose), shift and overlap (fraction of the
        cell's valid pixels on the target's) of each cell at its best pose.
    k : (n,) int
        Index of its best angle.
    """
    K = len(angles)
    if coarse <= 1:
        p = problem(1)
        n = len(p["cells"].ca)
        best = np.full((K, n, 4), np.nan)
        zeros = np.zeros(n, int)
        for k, theta in enumerate(angles):
            B, MB, _ = rotated(p["zmb"], theta, p["cb"], p["ca"], p["frame"])
            best[k] = np.stack(search(p["cells"], np.arange(n), B, MB, zeros, zeros,
                                      *p["half"], p["half"]), 1)
        return _pick(best)
    f = int(coarse)
    pc = problem(f)
    n = len(pc["cells"].ca)
    zeros = np.zeros(n, int)
    rough = np.full((K, n, 4), np.nan)
    for k, theta in enumerate(angles):
        B, MB, _ = rotated(pc["zmb"], theta, pc["cb"], pc["ca"], pc["frame"])
        rough[k] = np.stack(search(pc["cells"], np.arange(n), B, MB, zeros, zeros,
                                   *pc["half"], pc["half"]), 1)
    kc = _pick(rough)[-1]
    p = problem(1)
    best = np.full((K, n, 4), np.nan)
    win = 2 * f
    for k, theta in enumerate(angles):
        idx = np.flatnonzero((np.abs(kc - k) <= refine) & np.isfinite(rough[k, :, 0]))
        if not len(idx):
            continue
        B, MB, _ = rotated(p["zmb"], theta, p["cb"], p["ca"], p["frame"])
        cy = (f * rough[k, idx, 1]).astype(int)
        cx = (f * rough[k, idx, 2]).astype(int)
        best[k, idx] = np.stack(search(p["cells"], idx, B, MB, cy, cx, win, win,
                                       p["half"]), 1)
    return _pick(best)


def _pick(best):
    score = np.where(np.isfinite(best[..., 0]), best[..., 0], -np.inf)
    k = score.argmax(0)
    sel = best[k, np.arange(best.shape[1])]
    return sel[:, 0], sel[:, 1], sel[:, 2], sel[:, 3], k
