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
coarse, refine            2, 1         psbench's coarse-to-fine search (below); ``coarse=1``
                                       is cmcR's exhaustive search
========================  ===========  ==================================================

Where psbench departs from cmcR: the cell's correlation over translations is a
*locally normalised* FFT correlation (numerator ``sum a b``, denominator the cell's
energy times the target's energy under the cell's valid pixels) instead of cmcR's
globally normalised one, so that a cell is not drawn to the loudest patch of the target
or into its missing data; as in cmcR, the reported CCF of a cell is then the Pearson
correlation of the common valid pixels at that translation. Translations are in
pixels, as cmcR's, so on images at another pixel size than 6.25 µm convert the
tolerance (``translation_tol = 125 / pixel_size`` keeps cmcR's 125 µm).

Chance congruence (why unrelated fields can reach the threshold). A chance congruent
cell needs a CCF >= ``min_ccf`` *and* a pose within the tolerances of the median; the
second has probability ~ (41 / searched translations per axis)^2 x (5 / 21 angles) for
the defaults. Band-limited random fields (Gaussian-smoothed noise, sigma 2 px, on a
disc; 8 unrelated pairs per size): at 256 px the 8 x 8 cells are 31 px, hold ~20
independent samples of the field (cell area / 4 pi sigma^2), and 49 of 60 reach CCF 0.5
by chance (median 0.55), so ~10 % of them agree with the median by chance: 3.9 congruent
cells on average, at most 9. min_valid 0.5 instead of 0.15 leaves 3.5 (at most 6) of 52:
the missing data are not the cause. At 384 px (47 px cells) 0.6 (at most 2); at 556 px
(66 px cells, ~90 samples: 2 of 54 cells reach 0.5) 0 on every pair, as on the 27
different-gun pairs of shared scans above (0-2). The fix is the field's convention
already in the defaults -- 8 x 8 cells over a whole breech face at ~6 µm per pixel,
cells of ~70 px -- not a constant: smaller cells (or much smoother data) make CCF 0.5
and the 20 px tolerance meaningless.

Search (:mod:`psbench.forensic._cmc_search`): every angle and translation is tried on
2 x 2 block means of both maps (``coarse=2``), then each cell is registered again at full
resolution at its best coarse angle and one neighbouring angle on each side, within
4 px of the coarse translation at that angle (``coarse=1``: the exhaustive full-resolution
search, cmcR's). Per angle the target is rotated once for all cells (the refinement
warps only the few small regions it searches); the cells' correlations over all
translations are one batch of real FFTs; no loop over pixels.
Measured on 36 pairs of 9 shared scans (guns 1-3, 9 same-gun pairs), coarse-to-fine
against exhaustive: same-gun consensus poses equal within 0.5 px and 0 deg on all 9,
CCFmax within 0.006, counts 0.8 lower on average (at most 3 of ~33), 96 % of the
exhaustive search's congruent cells found at the same pose (within 1 px, one angle
step); different-gun counts within 1 (mean +0.04). Time per pair 0.33 x the exhaustive
search's (median over the 36 pairs, load average ~10 on 2 cores;
benchmarks/bench_cmc.py). CCFmax of the whole scans is measured at the consensus pose,
with a small translation search around it (:func:`cmc` ``ccf``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._shared.checks import PsbenchError, as_mask
from .._shared.checks import workers as check_workers
from . import _cmc_search as _ccs
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
        the cell with data), ``overlap`` (fraction of those on the target's data at
        the cell's pose), ``ccf`` (Pearson correlation at the cell's best pose),
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


_rotated, _pearson = _ccs.rotated, _ccs.pearson


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
        ccf_search=3, coarse=2, refine=1, workers=-1):
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
    coarse : int, default 2
        Block size of the first search: every angle and translation is tried on
        ``coarse`` x ``coarse`` block means, then each cell is registered again at
        full resolution at its best coarse angle and ``refine`` neighbouring angles on
        each side, within ``2 * coarse`` pixels of the coarse translation (psbench's
        speed-up, about 3x; ``coarse=1`` searches every angle and translation at full
        resolution, as cmcR does).
    refine : int, default 1
        Neighbouring angles (each side) re-registered at full resolution.
    workers : int, default -1
        Threads of the Fourier transforms (-1: one per core). Studies that compare
        pairs in several processes at once pass 1.

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
    for name, v, low in (("coarse", coarse, 1), ("refine", refine, 0)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < low:
            raise PsbenchError(f"{name} must be an integer >= {low}, got {v!r}")
    workers = check_workers(workers, "workers")
    ang = np.sort(ang)           # the refinement's neighbouring angles are neighbours here
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
    grid = [(i, j, r0 + i * ch, c0 + j * cw) for i in range(nr) for j in range(nc)]
    tops0 = np.array([g[2] for g in grid])
    lefts0 = np.array([g[3] for g in grid])
    # valid fraction of each cell (cells may reach past the map: that part is missing)
    mpad = np.zeros((za.shape[0] + ch, za.shape[1] + cw), bool)
    mpad[:za.shape[0], :za.shape[1]] = ma
    frac = _ccs.sliding_window_view(mpad, (ch, cw))[tops0, lefts0].mean((1, 2))
    keep = frac >= float(min_valid)
    if keep.sum() < 2:
        raise PsbenchError(f"fewer than 2 cells of the reference have >= {min_valid} valid "
                           "pixels; use fewer cells or a lower min_valid")
    grid = [g for g, k in zip(grid, keep) if k]
    tops0, lefts0, frac = tops0[keep], lefts0[keep], frac[keep]
    cb, cen_a = _centre(mb), _centre(ma)
    f_coarse = max(1, int(coarse))

    def problem(f):
        """The search at block size f: frames padded so every target region fits."""
        if f == 1:
            a, m_a, b, m_b = za, ma, zb, mb
        else:
            a, m_a = _ccs.downsample(za, ma, f)
            b, m_b = _ccs.downsample(zb, mb, f)
        hy, hx = ph // f, pw // f
        c_h, c_w = max(2, ch // f), max(2, cw // f)
        pad = -(-(max(ph, pw) + 2 * f_coarse + max(nr, nc) + 2) // f)
        frame = (a.shape[0] + 2 * pad, a.shape[1] + 2 * pad)
        A = np.zeros(frame, np.float32)
        MA = np.zeros(frame, bool)
        A[pad:pad + a.shape[0], pad:pad + a.shape[1]] = a
        MA[pad:pad + a.shape[0], pad:pad + a.shape[1]] = m_a
        to = lambda c: (np.asarray(c, float) - (f - 1) / 2) / f  # noqa: E731 block coords
        cel = _ccs.Cells(A, MA, tops0 // f + pad, lefts0 // f + pad, c_h, c_w,
                         max(4.0, 16.0 / f ** 2))
        return {"cells": cel, "zmb": _ccs.stacked(b, m_b), "cb": to(cb), "ca": to(cen_a) + pad,
                "frame": frame, "half": (hy, hx) if f > 1 else (ph, pw)}

    cell_ccf, sy, sx, overlap, kbest = _ccs.register_cells(
        problem, ang, coarse=f_coarse, refine=int(refine), workers=workers)
    # the shift s moves the cell onto the rotated target: the target's pose is -s
    dy, dx, theta = -sy, -sx, ang[kbest]
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
        "top": tops0, "left": lefts0, "height": ch, "width": cw,
        "valid": frac, "overlap": overlap, "ccf": cell_ccf, "dx": dx, "dy": dy, "theta": theta,
        "congruent": congruent})
    return CmcResult(int(congruent.sum()), table, pose, ccf)


def _ccfmax(za, ma, zb, mb, cb, ca, med, step, radius):
    """Whole-map Pearson correlation maximised near the consensus pose (hill climb over
    integer translations within ``radius`` px of it and rotation in shrinking steps)."""
    H, W = za.shape
    R = int(radius)
    zmb = _ccs.stacked(zb, mb)
    # the reference's valid pixels, as flat indices into the R px larger frame
    yy, xx = np.nonzero(ma)
    base = (yy + R) * (W + 2 * R) + (xx + R)
    a = za[yy, xx].astype(np.float64)
    warped = {}

    def corr(i, j, th):
        # one warp per angle, into a frame R px larger: integer shifts are slices of it
        if th not in warped:
            B, MB, M = _rotated(zmb, th, cb, (ca[0] + R, ca[1] + R),
                                (H + 2 * R, W + 2 * R), (med[0], med[1]))
            warped[th] = B.ravel(), MB.ravel(), M
        B, MB, M = warped[th]
        at = base - j * (W + 2 * R) - i
        both = MB[at]
        r = _pearson(a[both][None], B[at][both][None].astype(np.float64), None, 64)[0]
        M = M.copy()
        M[:, 2] += (i - R, j - R)
        return (r if np.isfinite(r) else -np.inf), M

    i = j = 0
    t = med[2]
    val, M = corr(i, j, t)
    dt = step / 2.0
    for _ in range(3):          # translation steps of 1 px, angle steps step/2, /4, /8
        improved = True
        while improved:
            improved = False
            for di, dj, ddt in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0),
                                (0, 0, dt), (0, 0, -dt)):
                ni, nj, nt = i + di, j + dj, t + ddt
                if abs(ni) > R or abs(nj) > R or abs(nt - med[2]) > step:
                    continue
                v, Mv = corr(ni, nj, nt)
                if v > val:
                    val, M, i, j, t, improved = v, Mv, ni, nj, nt, True
        dt /= 2.0
    return (float(val) if np.isfinite(val) else float("nan")), \
        Pose(float(med[0] + i), float(med[1] + j), float(t), M)
