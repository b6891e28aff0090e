"""Congruent matching cells (CMC) of two breech-face topographies.

The CMC method (Song, "Proposed NIST ballistics identification system (NBIS) based on
3D topography measurements on correlation cells", AFTE J. 45 (2013) 184-194; Song et
al., Forensic Sci. Int. 284 (2018) 15-32) divides the *reference* into a grid of cells
and registers each cell on the *target* on its own, over translation and rotation. On a
same-gun pair many cells find the same pose (the gun's marks are shared); on a
different-gun pair each cell lands wherever the noise happens to correlate. A cell is a
congruent matching cell when

- its correlation at its best pose is at least ``min_ccf`` and
- its translation and rotation agree with the consensus pose of all cells within
  ``translation_tol`` pixels (each of dx, dy) and ``rotation_tol`` degrees.

The consensus is the median of the cells' poses (Song 2013's "original" decision rule,
as in the open-source reference implementation, the R package cmcR: Zemmels, Hofmann
and VanderPlas, "cmcR: an R package for the congruent matching cells method",
``decision_CMC(method = "original")``). Two cases are called a match when the count
reaches ``C = 6`` (:data:`CMC_THRESHOLD`, Song 2013's identification criterion).

Defaults and where they come from (cmcR's defaults unless said otherwise):

========================  ===========  ==================================================
parameter                 default      source
========================  ===========  ==================================================
band-pass                 16-500 µm    cmcR ``preProcess_gaussFilter(wavelength =
                                       c(16, 500))``, ISO 16610-61 Gaussian regression
cells                     (8, 8)       cmcR ``comparison_cellDivision(numCells = c(8, 8))``
min_valid                 0.15         cmcR ``comparison_allTogether(maxMissingProp =
                                       .85)``: cells more than 85 % missing are dropped
region                    3            target region 3 x the cell side (cmcR
                                       ``regionSizeMultiplier = 9``, an area factor)
angles                    -30:3:30 deg cmcR's vignette ``thetas = seq(-30, 30, by = 3)``
translation_tol           20 px        cmcR ``xThresh = yThresh = 20`` (pixels at its
                                       6.25 µm working resolution, i.e. 125 µm)
rotation_tol              6 deg        cmcR ``thetaThresh = 6``
min_ccf                   0.5          cmcR ``corrThresh = .5``
========================  ===========  ==================================================

Where psbench departs from cmcR: the cell's correlation over translations is a
*locally normalised* FFT correlation (numerator ``sum a b``, denominator the cell's
energy times the target's energy under the cell's valid pixels) instead of cmcR's
globally normalised one, so that a cell is not drawn to the loudest patch of the target
or into its missing data; as in cmcR, the reported CCF of a cell is then the Pearson
correlation of the common valid pixels at that translation. Translations are in
pixels, as cmcR's, so on images at another pixel size than 6.25 µm convert the
tolerance (``translation_tol = 125 / pixel_size`` keeps cmcR's 125 µm).

Cost: per angle, three batched forward transforms of the target regions (values,
squares, mask) and three inverse ones (correlation, target energy and overlap under
each cell) over all cells at once; no loop over pixels. Two ~560^2 shared scans (33
cells, 21 angles, 216^2 transforms): 2.6 s per pair on 2 shared cores at a load average
of ~4.5 (benchmarks/bench_cmc.py; whole-map :func:`~psbench.forensic.compare` 0.85 s in
the same run), of which ~55 % are the transforms. CCFmax of the whole scans is measured at the consensus pose, with
a small translation search around it (:func:`cmc` ``ccf``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
import scipy.fft as sfft

from .._shared.checks import PsbenchError, as_mask
from .cartridge import check_pixel_size
from .identify import bandpass as _bandpass

__all__ = ["CMC_THRESHOLD", "CMC_DEFAULTS", "CmcResult", "Pose", "cmc"]

#: Song (2013): a pair with at least this many congruent matching cells is called a match
CMC_THRESHOLD = 6
#: the defaults of :func:`cmc` (see the module's table for their sources)
CMC_DEFAULTS = {"short": 16.0, "long": 500.0, "cells": (8, 8), "min_valid": 0.15,
                "region": 3.0, "angles": tuple(range(-30, 31, 3)), "translation_tol": 20.0,
                "rotation_tol": 6.0, "min_ccf": 0.5}


@dataclass(frozen=True)
class Pose:
    """A rigid pose of the target on the reference.

    Rotating the target counter-clockwise (as displayed) by ``theta`` degrees about the
    centre of its valid region's bounding box, putting that centre on the reference's
    and then shifting it by ``dx`` columns (right) and ``dy`` rows (down) lays it on the
    reference. ``matrix`` is the same map as a (2, 3) affine of target pixel
    coordinates (column, row) onto reference ones.
    """

    dx: float
    dy: float
    theta: float
    matrix: np.ndarray = field(repr=False, default=None)


@dataclass(eq=False)
class CmcResult:
    """Result of :func:`cmc`.

    Attributes
    ----------
    count : int
        Number of congruent matching cells.
    cells : DataFrame
        One row per reference cell that took part: ``row, col`` (grid index),
        ``top, left, height, width`` (pixels in the reference), ``valid`` (fraction of
        the cell with data), ``ccf`` (Pearson correlation at the cell's best pose),
        ``dx, dy, theta`` (its pose, as :class:`Pose`), ``congruent`` (bool).
    pose : Pose
        Consensus pose (median of the cells' poses).
    ccf : float
        CCFmax: Pearson correlation of the two whole band-passed maps at the best pose
        near the consensus.
    threshold : int
        :data:`CMC_THRESHOLD`; ``match`` is ``count >= threshold``.
    """

    count: int
    cells: object
    pose: Pose
    ccf: float
    threshold: int = CMC_THRESHOLD

    @property
    def match(self):
        return self.count >= self.threshold


def _centre(m):
    rr, cc = np.nonzero(m)
    return 0.5 * (cc.min() + cc.max()), 0.5 * (rr.min() + rr.max())


def _bbox(m):
    rr, cc = np.nonzero(m)
    return rr.min(), rr.max() + 1, cc.min(), cc.max() + 1


def _rotated(z, m, theta, cb, ca, shape, shift=(0.0, 0.0)):
    """Target rotated by ``theta`` about ``cb``, ``cb`` put on ``ca`` (+ shift), in a frame
    of ``shape``; values 0 and mask False where there is no data."""
    M = cv2.getRotationMatrix2D((float(cb[0]), float(cb[1])), float(theta), 1.0)
    M[:, 2] += (ca[0] - cb[0] + shift[0], ca[1] - cb[1] + shift[1])
    size = (shape[1], shape[0])
    zr = cv2.warpAffine(z, M, size, flags=cv2.INTER_LINEAR, borderValue=0.0)
    wr = cv2.warpAffine(m.astype(np.float32), M, size, flags=cv2.INTER_LINEAR, borderValue=0.0)
    mr = wr > 0.999   # only pixels whose four neighbours all carry data
    return np.where(mr, zr, 0.0).astype(np.float32), mr, M


def _pearson(x, y, m, min_count):
    """Row-wise Pearson correlation of (n, P) arrays over mask ``m``; NaN if too few."""
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


def _check_options(cells, min_valid, region, angles, translation_tol, rotation_tol, min_ccf):
    try:
        nr, nc = (int(v) for v in cells)
    except (TypeError, ValueError):
        raise PsbenchError(f"cells must be a (rows, cols) pair of integers, got {cells!r}") from None
    if nr < 1 or nc < 1 or nr * nc < 2:
        raise PsbenchError(f"cells must be a (rows, cols) pair >= 1 with at least 2 cells, "
                           f"got {cells!r}")
    if not 0 < float(min_valid) <= 1:
        raise PsbenchError(f"min_valid must be in (0, 1], got {min_valid!r}")
    if not float(region) >= 1.5:
        raise PsbenchError(f"region must be >= 1.5 (target side / cell side), got {region!r}")
    ang = np.atleast_1d(np.asarray(angles, float))
    if ang.ndim != 1 or not len(ang) or not np.isfinite(ang).all():
        raise PsbenchError(f"angles must be a non-empty sequence of degrees, got {angles!r}")
    for name, v in (("translation_tol", translation_tol), ("rotation_tol", rotation_tol)):
        if not (math.isfinite(float(v)) and float(v) >= 0):
            raise PsbenchError(f"{name} must be a finite number >= 0, got {v!r}")
    if not -1 <= float(min_ccf) <= 1:
        raise PsbenchError(f"min_ccf must be in [-1, 1], got {min_ccf!r}")
    return nr, nc, ang


def cmc(height_a, height_b, valid_a=None, valid_b=None, *, pixel_size,
        short=CMC_DEFAULTS["short"], long=CMC_DEFAULTS["long"], filtered=False,
        cells=CMC_DEFAULTS["cells"], min_valid=CMC_DEFAULTS["min_valid"],
        region=CMC_DEFAULTS["region"], angles=CMC_DEFAULTS["angles"],
        translation_tol=CMC_DEFAULTS["translation_tol"],
        rotation_tol=CMC_DEFAULTS["rotation_tol"], min_ccf=CMC_DEFAULTS["min_ccf"],
        ccf_search=3):
    """Congruent matching cells of reference ``a`` on target ``b``.

    Parameters
    ----------
    height_a, height_b : (H, W) array_like
        Heights in µm (any two shapes at the same pixel size). NaN counts as missing.
    valid_a, valid_b : (H, W) bool, optional
        Pixels that carry data (default: the finite ones).
    pixel_size : float
        µm per pixel of both maps.
    short, long : float, default 16, 500
        Band-pass cut-offs in µm (ISO 16610-61 Gaussian regression filter,
        :func:`psbench.forensic.bandpass`); cmcR's defaults.
    filtered : bool, default False
        The heights are already band-passed: skip the filter.
    cells : (int, int), default (8, 8)
        Grid of cells over the bounding box of the reference's valid region.
    min_valid : float, default 0.15
        Cells with a smaller fraction of valid pixels are left out.
    region : float, default 3
        Side of the target region searched for each cell, in cell sides (the search
        covers translations up to ``(region - 1) / 2`` cell sides from the cell's place).
    angles : sequence of float, default -30, -27, ..., 30
        Rotations of the target tried, degrees.
    translation_tol : float, default 20
        Largest |dx| and |dy| (pixels) of a congruent cell from the consensus.
    rotation_tol : float, default 6
        Largest |theta| (degrees) of a congruent cell from the consensus.
    min_ccf : float, default 0.5
        Smallest correlation of a congruent cell.
    ccf_search : int, default 3
        CCFmax: the whole-map correlation is maximised over translations within this
        many pixels and rotations within one angle step (halved twice) of the
        consensus pose.

    Returns
    -------
    CmcResult
    """
    import pandas as pd

    ps = check_pixel_size(pixel_size)
    za = np.asarray(height_a, np.float32)
    zb = np.asarray(height_b, np.float32)
    for name, z in (("height_a", za), ("height_b", zb)):
        if z.ndim != 2:
            raise PsbenchError(f"{name} must have shape (H, W), got {z.shape}")
    ma = as_mask(valid_a, za.shape, "valid_a") & np.isfinite(za)
    mb = as_mask(valid_b, zb.shape, "valid_b") & np.isfinite(zb)
    if ma.sum() < 64 or mb.sum() < 64:
        raise PsbenchError("valid_a and valid_b must each hold at least 64 pixels with data")
    nr, nc, ang = _check_options(cells, min_valid, region, angles, translation_tol,
                                 rotation_tol, min_ccf)
    if not filtered:
        za = _bandpass(np.where(ma, za, 0), ma, pixel_size=ps, short=short, long=long)
        zb = _bandpass(np.where(mb, zb, 0), mb, pixel_size=ps, short=short, long=long)
    za = np.where(ma, za, 0).astype(np.float32)
    zb = np.where(mb, zb, 0).astype(np.float32)

    # cells over the reference's valid bounding box, all of one size
    r0, r1, c0, c1 = _bbox(ma)
    ch, cw = int(math.ceil((r1 - r0) / nr)), int(math.ceil((c1 - c0) / nc))
    if ch < 4 or cw < 4:
        raise PsbenchError(f"cells={cells!r} makes cells of {ch} x {cw} pixels; use fewer cells")
    ph, pw = int(round((region - 1) / 2 * ch)), int(round((region - 1) / 2 * cw))
    th, tw = ch + 2 * ph, cw + 2 * pw                   # target region
    fh, fw = sfft.next_fast_len(th, real=True), sfft.next_fast_len(tw, real=True)
    # reference frame padded so every target region lies inside it
    frame = (za.shape[0] + 2 * ph + ch, za.shape[1] + 2 * pw + cw)
    off = np.array([ph, pw])
    A = np.zeros(frame, np.float32)
    MA = np.zeros(frame, bool)
    A[ph:ph + za.shape[0], pw:pw + za.shape[1]] = za
    MA[ph:ph + za.shape[0], pw:pw + za.shape[1]] = ma
    grid = [(i, j, r0 + i * ch, c0 + j * cw) for i in range(nr) for j in range(nc)]
    tops = np.array([g[2] for g in grid]) + off[0]
    lefts = np.array([g[3] for g in grid]) + off[1]
    ri = np.arange(ch)[None, :, None]
    ci = np.arange(cw)[None, None, :]
    cm = MA[tops[:, None, None] + ri, lefts[:, None, None] + ci]
    frac = cm.mean((1, 2))
    keep = frac >= float(min_valid)
    if keep.sum() < 2:
        raise PsbenchError(f"fewer than 2 cells of the reference have >= {min_valid} valid "
                           "pixels; use fewer cells or a lower min_valid")
    grid = [g for g, k in zip(grid, keep) if k]
    tops, lefts, cm, frac = tops[keep], lefts[keep], cm[keep], frac[keep]
    n = len(grid)
    ca_ = A[tops[:, None, None] + ri, lefts[:, None, None] + ci]
    # zero-mean cells over their valid pixels, at the FFT frame's origin: the circular
    # correlation at index t = s + (ph, pw) (shift s in [-ph, ph]) never wraps
    cnt = cm.sum((1, 2))
    ca_ = np.where(cm, ca_ - ((ca_ * cm).sum((1, 2)) / cnt)[:, None, None], 0).astype(np.float32)
    pad = np.zeros((n, fh, fw), np.float32)
    pad[:, :ch, :cw] = ca_
    FA = np.conj(sfft.rfft2(pad, workers=-1))
    pad[:] = 0
    pad[:, :ch, :cw] = cm
    FM = np.conj(sfft.rfft2(pad, workers=-1))
    energy = (ca_ * ca_).sum((1, 2))
    need = np.maximum(16.0, 0.5 * cnt) - 0.5
    min_count = need

    cb, cen_a = _centre(mb), _centre(ma)
    cen_frame = (cen_a[0] + pw, cen_a[1] + ph)
    # per angle: best translation of each cell by the locally normalised FFT
    # correlation, then the Pearson correlation of the common valid pixels there
    best = np.full((len(ang), n, 3), np.nan)   # ccf, sy, sx
    tr = np.arange(th)[None, :, None]
    tc = np.arange(tw)[None, None, :]
    ys, xs = np.arange(2 * ph + 1) - ph, np.arange(2 * pw + 1) - pw
    for k, theta in enumerate(ang):
        B, MB, _ = _rotated(zb, mb, theta, cb, cen_frame, frame)
        rb = B[(tops - ph)[:, None, None] + tr, (lefts - pw)[:, None, None] + tc]
        pad[:] = 0
        pad[:, :th, :tw] = rb
        FB = sfft.rfft2(pad, workers=-1)
        pad[:, :th, :tw] = rb * rb
        FB2 = sfft.rfft2(pad, workers=-1)
        pad[:, :th, :tw] = MB[(tops - ph)[:, None, None] + tr, (lefts - pw)[:, None, None] + tc]
        FMB = sfft.rfft2(pad, workers=-1)
        num = sfft.irfft2(FA * FB, s=(fh, fw), workers=-1)
        den = sfft.irfft2(FM * FB2, s=(fh, fw), workers=-1)
        over = sfft.irfft2(FM * FMB, s=(fh, fw), workers=-1)
        # index t: cell pixel u against region pixel u + t, i.e. shift s = t - (ph, pw)
        num = num[:, :2 * ph + 1, :2 * pw + 1]
        den = den[:, :2 * ph + 1, :2 * pw + 1]
        over = over[:, :2 * ph + 1, :2 * pw + 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            score = num / np.sqrt(np.maximum(den, 1e-12) * energy[:, None, None])
        # too small an overlap correlates by chance: at least half the cell's data
        score[~np.isfinite(score) | (over < need[:, None, None])] = -np.inf
        flat = score.reshape(n, -1).argmax(1)
        iy, ix = np.divmod(flat, 2 * pw + 1)
        sy, sx = ys[iy], xs[ix]
        rr = tops[:, None, None] + sy[:, None, None] + ri
        cc = lefts[:, None, None] + sx[:, None, None] + ci
        pb, pm = B[rr, cc], MB[rr, cc]
        both = (cm & pm).reshape(n, -1)
        r = _pearson(ca_.reshape(n, -1), pb.reshape(n, -1), both, min_count)
        best[k] = np.stack([r, sy, sx], 1)

    score = np.where(np.isfinite(best[..., 0]), best[..., 0], -np.inf)
    kbest = score.argmax(0)
    sel = best[kbest, np.arange(n)]
    cell_ccf = sel[:, 0]
    # the shift s moves the cell onto the rotated target: the target's pose is -s
    dy, dx, theta = -sel[:, 1], -sel[:, 2], ang[kbest]
    ok = np.isfinite(cell_ccf)
    if ok.any():
        med = (float(np.median(dx[ok])), float(np.median(dy[ok])), float(np.median(theta[ok])))
    else:
        med = (0.0, 0.0, 0.0)
    congruent = (ok & (np.nan_to_num(cell_ccf, nan=-2) >= float(min_ccf))
                 & (np.abs(dx - med[0]) <= float(translation_tol))
                 & (np.abs(dy - med[1]) <= float(translation_tol))
                 & (np.abs(theta - med[2]) <= float(rotation_tol)))
    step = float(np.min(np.diff(np.sort(ang)))) if len(ang) > 1 else 1.0
    ccf, pose = _ccfmax(za, ma, zb, mb, cb, cen_a, med, step, int(ccf_search))
    table = pd.DataFrame({
        "row": [g[0] for g in grid], "col": [g[1] for g in grid],
        "top": tops - off[0], "left": lefts - off[1], "height": ch, "width": cw,
        "valid": frac, "ccf": cell_ccf, "dx": dx, "dy": dy, "theta": theta,
        "congruent": congruent})
    return CmcResult(int(congruent.sum()), table, pose, ccf)


def _ccfmax(za, ma, zb, mb, cb, ca, med, step, radius):
    """Whole-map Pearson correlation maximised near the consensus pose (hill climb over
    translation within ``radius`` px and rotation in shrinking steps)."""
    shape = za.shape

    def corr(dx, dy, th):
        B, MB, M = _rotated(zb, mb, th, cb, ca, shape, (dx, dy))
        both = (ma & MB).reshape(1, -1)
        r = _pearson(za.reshape(1, -1), B.reshape(1, -1), both, 64)[0]
        return (r if np.isfinite(r) else -np.inf), M

    x, y, t = med
    val, M = corr(x, y, t)
    moves, dt = 1.0, step / 2.0
    for _ in range(3):          # translation steps 1 px, then angle steps step/2, /4, /8
        improved = True
        while improved:
            improved = False
            for ddx, ddy, ddt in ((moves, 0, 0), (-moves, 0, 0), (0, moves, 0),
                                  (0, -moves, 0), (0, 0, dt), (0, 0, -dt)):
                nx, ny, nt = x + ddx, y + ddy, t + ddt
                if abs(nx - med[0]) > radius or abs(ny - med[1]) > radius \
                        or abs(nt - med[2]) > step:
                    continue
                v, Mv = corr(nx, ny, nt)
                if v > val:
                    val, M, x, y, t, improved = v, Mv, nx, ny, nt, True
        dt /= 2.0
    return (float(val) if np.isfinite(val) else float("nan")), Pose(float(x), float(y), float(t), M)
