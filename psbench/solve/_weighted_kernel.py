"""Compiled per-pixel pass of :func:`psbench.solve.weighted.weighted_masks` (numba).

One pass over the observations replaces the per-light chain of numpy temporaries
(Lambert image, residual, Eq. 3.19's sigma, its square and inverse). Every output
element depends on its own pixel only, so the result does not depend on the thread
count.

Pixels run on numba's threads (``prange``; psbench selects numba's fork-safe threading
layer, :mod:`psbench._shared.numba_setup`, so psbench's forked runs may use them).
"""
from __future__ import annotations

import numpy as np
from numba import njit, prange

__all__ = ["inverse_variances"]


@njit(cache=True, nogil=True, parallel=True)
def inverse_variances(images, b, S, valid, smin, out):
    """``out[i] = 1 / sigma_i^2`` with Eq. 3.19's sigma in units of ``smin``.

    sigma_i = |I_i - s_i . b| / smin where observation i is masked (``valid`` False)
    and that residual is at least ``smin``, else 1.

    Parameters
    ----------
    images : (k, H, W) float32
    b : (H, W, 3) float32
    S : (k, 3) float32
    valid : (k, H, W) bool
    smin : float32
    out : (k, H, W) float32
    """
    k, H, W = images.shape
    one = np.float32(1.0)
    for r in prange(H):
        for i in range(k):
            s0, s1, s2 = S[i, 0], S[i, 1], S[i, 2]
            for c in range(W):
                w = one
                if not valid[i, r, c]:
                    lam = b[r, c, 0] * s0 + b[r, c, 1] * s1 + b[r, c, 2] * s2
                    res = abs(images[i, r, c] - lam)
                    if res >= smin:
                        sig = res / smin
                        w = one / (sig * sig)
                out[i, r, c] = w
    return out
