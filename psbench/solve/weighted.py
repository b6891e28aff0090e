"""Weighted PS (Section 3.4): weighted masks (Eq. 3.19) and FWLSE (Section 3.4.1).

Both end in one call of :func:`psbench.solve.kernel.wls` with per-observation
weights = inverse variances.

Weighted masks (Section 3.4.2, Eq. 3.19), run once after the binary masked solve:

1. L = rho s.n from the binary solution;
2. sigma_i = |I_i - L_i| where the observation is **masked** and |I - L| >= sigma_min,
   else sigma_min;
3. the variance images sigma_i^2 are dilated with a disk (radius ``dilate_radius``,
   default 7, in a ``kernel_size`` square, default 15) -- enlarging the masked regions;
4. the inverse variances 1/sigma_i^2 are smoothed with a Gaussian (``smooth_sigma``,
   default 3, ``kernel_size`` x ``kernel_size``);
5. one WLS solve with those weights.

FWLSE (Section 3.4.1): start from the (masked) least-squares solution, set
sigma_i = max(|I_i - L_i|, sigma_min) -- psbench uses the absolute residual as Eq.
3.19 does; Eq. 3.15 as printed would give every negative residual (shadows) the
minimum variance, i.e. full weight -- and solve WLS with weights valid_i / sigma_i^2;
repeat until the largest change of a variance between two iterations is below
``fwlse_tol * R^2`` (R = mean dynamic range of the images; default 1e-3) or
``max_iter``. The criterion is a maximum over every observation: on TS scenes a
few pixels keep switching between near-equal consensus sets for many iterations
(1/r^2 reweighting is close to an L0 fit), so a much smaller tolerance rarely stops
before ``max_iter``.

``sigma_min`` defaults to 0.01 R (1 % of the mean dynamic range).
"""
from __future__ import annotations

import numpy as np

from . import kernel

__all__ = ["disk", "weighted_masks", "fwlse", "DEFAULTS"]

DEFAULTS = {"dilate_radius": 7, "smooth_sigma": 3.0, "kernel_size": 15, "sigma_min": None,
            "fwlse_tol": 1e-3}


def disk(radius, size=None):
    """Disk structuring element (uint8) of ``radius`` pixels in a ``size`` square."""
    radius = int(radius)
    size = 2 * radius + 1 if size is None else int(size)
    c = (size - 1) / 2.0
    y, x = np.mgrid[:size, :size]
    return (((x - c) ** 2 + (y - c) ** 2) <= radius * radius + 1e-9).astype(np.uint8)


def weighted_masks(images, S, b, valid, *, sigma_min, dilate_radius=7, smooth_sigma=3.0,
                   kernel_size=15, out=None):
    """Weights of the weighted-mask PS (Eq. 3.19 and steps 4-5).

    Parameters
    ----------
    images : (k, H, W) float32
    S : (k, 3)
    b : (H, W, 3) float32
        Binary masked solution rho * n.
    valid : (k, H, W) bool
        Binary mask (True = used).
    sigma_min : float
        Minimum standard deviation (> 0).
    dilate_radius, smooth_sigma, kernel_size : see module doc. ``dilate_radius=0``
        and ``smooth_sigma=0`` skip the steps.
    out : (k, H, W) float32, optional
        Output array to fill.

    Returns
    -------
    weights : (k, H, W) float32
        Inverse variances normalised by sigma_min^2 (1 = fully trusted).
    """
    import cv2

    from ._weighted_kernel import inverse_variances

    k, H, W = images.shape
    S = np.asarray(S, dtype=np.float32)
    size = int(kernel_size)
    se = disk(min(int(dilate_radius), (size - 1) // 2), size) if dilate_radius > 0 else None
    weights = np.empty((k, H, W), dtype=np.float32) if out is None else out
    # Eq. 3.19 scaled by 1/sigma_min, inverted in the same pass: 1/sigma^2 (1 = trusted)
    inverse_variances(np.ascontiguousarray(images, dtype=np.float32),
                      np.ascontiguousarray(b, dtype=np.float32), S,
                      np.ascontiguousarray(valid, dtype=bool), np.float32(sigma_min), weights)
    tmp = np.empty((H, W), dtype=np.float32)
    for i in range(k):
        w = weights[i]
        if se is not None:
            # dilating sigma^2 then inverting == eroding 1/sigma^2 (1/x is monotone and
            # correctly rounded, so 1/max = min of 1/ exactly)
            cv2.erode(w, se, dst=tmp, borderType=cv2.BORDER_REPLICATE)
            w = tmp
        if smooth_sigma > 0:
            cv2.GaussianBlur(w, (size, size), sigmaX=float(smooth_sigma),
                             sigmaY=float(smooth_sigma), dst=weights[i],
                             borderType=cv2.BORDER_REPLICATE)
        elif w is not weights[i]:
            weights[i] = w
    return weights


def fwlse(images, S, b, valid=None, *, sigma_min, tol, max_iter=10, scale=1.0):
    """Feasible weighted least squares (Section 3.4.1).

    Parameters
    ----------
    images : (k, H, W) float32
    S : (k, 3)
    b : (H, W, 3) float32
        Starting solution (least squares, possibly masked).
    valid : (k, H, W) bool, optional
        Observations allowed at all (masked ones keep weight 0).
    sigma_min : float
    tol : float
        Stop when max |sigma^2_new - sigma^2_old| < tol * scale^2.
    max_iter : int

    Returns
    -------
    b : (H, W, 3) float32
    weights : (k, H, W) float32 (normalised by sigma_min^2)
    iterations : int
        WLS solves performed.
    converged : bool
    """
    k, H, W = images.shape
    S32 = np.asarray(S, dtype=np.float32)
    smin = np.float32(sigma_min)
    prev = None
    iters = 0
    converged = False
    weights = np.empty((k, H, W), dtype=np.float32)
    stop = np.float32(tol * scale * scale) / (smin * smin)
    for it in range(max(1, int(max_iter)) + 1):
        r = np.abs(images - kernel.lambert(b, S32))
        np.maximum(r, smin, out=r)
        r /= smin
        r *= r  # variance / sigma_min^2
        if prev is not None:
            change = float(np.max(np.abs(r - prev))) if r.size else 0.0
            if change < stop:
                converged = True
                break
        if it == max(1, int(max_iter)):
            break
        np.divide(np.float32(1.0), r, out=weights)
        if valid is not None:
            weights *= valid
        b = kernel.wls(images, S, weights)
        iters += 1
        prev = r
    if iters == 0:
        np.divide(np.float32(1.0), r, out=weights)
        if valid is not None:
            weights *= valid
    return b, weights, iters, converged
