"""Plumbing shared by the robust per-pixel methods (l1, sbl, rpca, M-estimators, trim).

The robust methods work on the object pixels only. The numpy ones (l1, sbl, rpca) use
an ``(n, k)`` layout (one row per object pixel, one column per image): per-pixel
reductions and sorts then run along the contiguous last axis, and the per-pixel 3x3
weighted normal equations are two matrix products. The compiled kernels
(:mod:`._robust_kernel`: trim, the M-estimators) read the ``(k, n)`` layout of the
images themselves (no transposed copy). :class:`Pixels` gathers a
:class:`~psbench.solve.base.Problem` into either layout on first use and scatters
results back into a :class:`~psbench.solve.base.Fit`.
"""
from __future__ import annotations

import warnings

import numpy as np

from ...base import Fit
from ..._sym3 import sym3_solve
from ...._shared.warn import ConvergenceWarning

__all__ = ["Pixels", "wls", "leverage", "masked_median", "weights_out"]

_IU = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))
#: observations per block of :meth:`Pixels.blocks` (1 MB of float32)
BLOCK_VALUES = 1 << 18


def _outer(S):
    """(k, 6) float32: the unique entries of s_i s_i^T (xx, xy, xz, yy, yz, zz)."""
    S = np.asarray(S, dtype=np.float64)
    return np.ascontiguousarray((S[:, :, None] * S[:, None, :])[:, _IU[0], _IU[1]],
                                dtype=np.float32)


class Pixels:
    """The object pixels of a problem as ``(n, k)`` arrays.

    Attributes
    ----------
    I : (n, k) float32
        Intensities of the object pixels.
    V : (n, k) bool
        ``problem.valid`` of the object pixels (observations the mask kept).
    all_valid : bool
        Every observation of the object is valid (fast paths need no masking).
    m : (n,) int
        Valid observations per pixel.
    S : (k, 3) float64 and S32 float32, outer : (k, 6) float32
    scale : float
        ``problem.scale`` (> 0), the unit of absolute tolerances.
    """

    def __init__(self, problem):
        images = problem.images
        k, H, W = images.shape
        self.k, self.H, self.W = k, H, W
        om = np.asarray(problem.object_mask, dtype=bool).reshape(-1)
        self.full = bool(om.all())
        self.idx = None if self.full else np.flatnonzero(om)
        flat = images.reshape(k, -1)
        vflat = np.asarray(problem.valid, dtype=bool).reshape(k, -1)
        n = flat.shape[1] if self.full else self.idx.size
        self._flat, self._n = flat, n
        vk = vflat if self.full else vflat[:, self.idx]
        self.all_valid = bool(vk.all())
        self._Ik = self._I = self._V = None
        if self.all_valid:  # a read-only view: no (n, k) copy
            self._V = np.broadcast_to(np.True_, (n, k))
            self.Vk = None
            self.m = np.full(n, k)
        else:
            self.Vk = np.ascontiguousarray(vk)
            self.m = self.Vk.sum(axis=0)
        self.S = problem.S
        self.S32 = self.S.astype(np.float32)
        self.outer = _outer(self.S)
        # (6, k) / (3, k) for the compiled kernels (contiguous along the images)
        self.outer_t = np.ascontiguousarray(self.outer.T)
        self.S32_t = np.ascontiguousarray(self.S32.T)
        self.scale = float(problem.scale) if problem.scale and problem.scale > 0 else 1.0
        self._problem = problem

    @property
    def n(self):
        return self._n

    @property
    def Ik(self):
        """(k, n) float32 intensities (images x pixels: the layout of the compiled
        kernels, which work on many pixels at once); a view when the object is the
        whole image."""
        if self._Ik is None:
            self._Ik = (np.ascontiguousarray(self._flat, dtype=np.float32) if self.full
                        else np.take(self._flat, self.idx, axis=1).astype(np.float32, copy=False))
        return self._Ik

    @property
    def I(self):  # noqa: E743 - the (n, k) intensities, built on first use
        if self._I is None:
            k, n, flat = self.k, self._n, self._flat
            I = np.empty((n, k), dtype=np.float32)
            step = max(256, BLOCK_VALUES // max(k, 1))
            for lo in range(0, n, step):   # block by block: in cache
                hi = min(n, lo + step)
                I[lo:hi] = (flat[:, lo:hi] if self.full else flat[:, self.idx[lo:hi]]).T
            self._I = I
        return self._I

    @I.setter
    def I(self, value):  # noqa: E743
        self._I = value

    @property
    def V(self):
        """(n, k) bool validity (a broadcast view when all valid), built on first use."""
        if self._V is None:
            self._V = np.ascontiguousarray(self.Vk.T)
        return self._V

    @V.setter
    def V(self, value):
        self._V = value

    def kernel_valid(self):
        """``V`` as the compiled kernels take it: the (k, n) bool array, or a (1, 1)
        placeholder when every observation is valid (the kernels then ignore it)."""
        if self.all_valid:
            return np.ones((1, 1), dtype=bool)
        return self.Vk

    def rows(self, sl):
        """A view of the pixels ``sl`` (a slice): ``I``, ``V`` and ``m`` restricted,
        everything else shared (for per-block processing that stays in cache)."""
        return self._subset(sl)

    def take(self, idx):
        """A view like :meth:`rows` of the pixels ``idx`` (an index array; copies)."""
        return self._subset(idx)

    def _subset(self, sel):
        sub = object.__new__(type(self))
        sub.__dict__.update(self.__dict__)
        sub.I = self.I[sel]
        sub._n = sub.I.shape[0]
        sub._Ik = sub.Vk = None
        sub.m = self.m[sel]
        sub.V = (np.broadcast_to(np.True_, sub.I.shape) if self.all_valid else self.V[sel])
        sub._start_rows = sel
        return sub

    def blocks(self, values=BLOCK_VALUES):
        """Slices of consecutive pixels holding about ``values`` observations each:
        per-pixel work done block by block keeps its temporaries in cache (and
        avoids a page fault per fresh multi-megabyte temporary)."""
        size = max(256, values // max(self.k, 1))
        return [slice(lo, min(self.n, lo + size)) for lo in range(0, self.n, size)]

    def start(self):
        """(n, 3) float32: the masked least-squares start of the problem (of the rows
        of a :meth:`rows` view)."""
        b = np.asarray(self._problem.start(), dtype=np.float32).reshape(-1, 3)
        b = b if self.full else b[self.idx]
        sl = getattr(self, "_start_rows", None)
        return np.ascontiguousarray(b if sl is None else b[sl])

    # ------------------------------------------------------------------ scatter back
    def image(self, values, fill=0, dtype=None):
        """(n, ...) per-pixel values -> (H, W, ...) array, ``fill`` off the object."""
        values = np.asarray(values)
        dtype = dtype or values.dtype
        out = np.full((self.H * self.W,) + values.shape[1:], fill, dtype=dtype)
        if self.full:
            out[:] = values
        else:
            out[self.idx] = values
        return out.reshape((self.H, self.W) + values.shape[1:])

    def stack(self, values, fill, *, kn=False):
        """(n, k) per-observation values (``kn``: (k, n)) -> (k, H, W), ``fill`` off
        the object."""
        values = np.asarray(values)
        if kn:
            if self.full:
                return values.reshape(self.k, self.H, self.W)
            out = np.full((self.k, self.H * self.W), fill, dtype=values.dtype)
            out[:, self.idx] = values
            return out.reshape(self.k, self.H, self.W)
        out = np.empty((self.k, self.H * self.W), dtype=values.dtype)
        if not self.full:
            out[:] = fill
        for sl in self.blocks():          # block-wise transpose: stays in cache
            if self.full:
                out[:, sl] = values[sl].T
            else:
                out[:, self.idx[sl]] = values[sl].T
        return out.reshape(self.k, self.H, self.W)

    def fit(self, name, b, *, valid=None, weights=None, iterations=0, converged=True,
            n_iter=None, info=None, kn=False):
        """Assemble a :class:`Fit` from per-pixel results (``valid`` / ``weights``
        (n, k), or (k, n) with ``kn``); non-finite solutions are
        replaced by the masked least-squares start (and flagged not converged), and
        pixels that did not converge are counted in ``info`` and warned about."""
        info = dict(info or {})
        b = np.asarray(b, dtype=np.float32)
        bad = ~np.isfinite(b).all(axis=1)
        per_pixel = np.ndim(converged) > 0
        if bad.any():
            b = b.copy()
            b[bad] = self.start()[bad]
            b[~np.isfinite(b).all(axis=1)] = 0.0
            if per_pixel:
                converged = np.asarray(converged) & ~bad
            else:
                converged = False
            info["nonfinite_pixels"] = int(bad.sum())
        if per_pixel:
            conv = np.asarray(converged, dtype=bool)
            n_bad = int((~conv).sum())
            info["converged_fraction"] = float(conv.mean()) if conv.size else 1.0
            conv_out = self.image(conv, fill=True)
        else:
            n_bad = 0 if converged else self.n
            conv_out = converged
        if n_bad:
            msg = (f"{name}: {n_bad} of {self.n} object pixels did not converge"
                   + (f" in n_iter={n_iter} iterations (a larger options.n_iter lets "
                      "them go on)" if n_iter is not None else ""))
            warnings.warn(msg, ConvergenceWarning, stacklevel=3)
            info.setdefault("warnings", []).append(msg)
        it_out = (self.image(np.asarray(iterations, dtype=np.int32), fill=0)
                  if np.ndim(iterations) > 0 else int(iterations))
        valid_out = None
        if valid is not None:
            valid_out = self.stack(np.asarray(valid, dtype=bool), fill=True, kn=kn)
        w_out = None
        if weights is not None:
            w_out = self.stack(np.asarray(weights, dtype=np.float32), fill=np.float32(0), kn=kn)
        return Fit(b=self.image(b, fill=0, dtype=np.float32), valid=valid_out, weights=w_out,
                   iterations=it_out, converged=conv_out, info=info)


# ---------------------------------------------------------------------- linear algebra
def wls(I, w, px, *, fallback=None, want_inverse=False, scratch=None):
    """Per-pixel weighted least squares in the (n, k) layout.

    Parameters
    ----------
    I : (n, k) float32
        Intensities.
    w : (n, k) float32 or bool
        Weights (0 / False = unused).
    px : Pixels
        For ``S`` and its outer products.
    fallback : (n, 3) float32, optional
        Solution kept where the weighted normal matrix is singular (fewer than three
        independent weighted observations); default: plain least squares.
    want_inverse : bool
        Also return the inverse normal matrices (n, 6) (0 where singular).
    scratch : (n, k) float32, optional
        Buffer for w * I.

    Returns
    -------
    b : (n, 3) float32
    ok : (n,) bool
        Non-singular pixels.
    inv : (n, 6) float32, only with ``want_inverse``
    """
    if w.dtype != np.float32:
        w = w.astype(np.float32)
    # (n, 6) and (n, 3) products, then contiguous (6, n) / (3, n) rows for the 3x3 algebra
    a = np.ascontiguousarray(np.matmul(w, px.outer).T)
    wi = np.multiply(w, I, out=scratch)
    r = np.ascontiguousarray(np.matmul(wi, px.S32).T)
    b, ok, cof, inv_det = sym3_solve(a, r)
    if not ok.all():
        bad = ~ok
        if fallback is None:
            P = np.linalg.pinv(px.S).astype(np.float32)
            b[bad] = I[bad] @ P.T
        else:
            b[bad] = fallback[bad]
    if want_inverse:
        inv = np.stack(cof, axis=1)
        inv *= inv_det[:, None]
        return b, ok, inv
    return b, ok


def leverage(inv, px):
    """s_i^T M^{-1} s_i for every observation, (n, k) float32, from (n, 6) inverses."""
    # off-diagonal entries appear twice in the quadratic form
    o = px.outer * np.array([1, 2, 2, 1, 2, 1], dtype=np.float32)
    return inv @ o.T


def masked_median(a, V, m, all_valid):
    """Median of each row of ``a`` (n, k) over its valid entries ``V`` (m of them).

    Even counts average the two middle values. Rows without valid entries give 0.
    """
    n, k = a.shape
    if all_valid:
        lo, hi = (k - 1) // 2, k // 2
        s = np.partition(a, [lo, hi] if hi != lo else lo, axis=1) if k > 32 else np.sort(a, axis=1)
        return 0.5 * (s[:, lo] + s[:, hi])
    s = np.where(V, a, np.float32(np.inf))
    s.sort(axis=1)
    mm = np.maximum(m, 1)
    lo = ((mm - 1) // 2)[:, None]
    hi = (mm // 2)[:, None]
    med = 0.5 * (np.take_along_axis(s, lo, 1)[:, 0] + np.take_along_axis(s, hi, 1)[:, 0])
    med[m == 0] = 0.0
    return med


def weights_out(w, V):
    """Weights scaled per pixel to a maximum of 1 (WLS is invariant to this), 0 where
    the observation was not valid."""
    w = np.where(V, w, np.float32(0))
    mx = w.max(axis=1, keepdims=True)
    np.divide(w, mx, out=w, where=mx > 0)
    return w.astype(np.float32, copy=False)
