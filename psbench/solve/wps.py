"""Weighted multi-zenith photometric stereo (WPS, thesis Section 4.3).

The lights are grouped by ring (``Layout.rings()``); each ring is solved on its own
(Eqs. 4.3-4.4), its residual is measured (Eqs. 4.5-4.8) and the albedo-scaled normals
of the rings are fused per pixel with normalised weights (Eqs. 4.9-4.11):

    rho n = sum_j w_j rho_j n_j,      sum_j w_j = 1.

Decisions (where the thesis leaves room)
----------------------------------------
* **Residual.** ``e_j`` is the RMS over ring j's observations of ``I - rho_j s . n_j``
  (Eq. 4.7-4.8 divided by sqrt(n_j)), so rings with different light counts compare
  fairly; for equal counts this only rescales both e's, which the weight
  normalisation cancels. With a mask, the RMS runs over the observations the mask
  kept.
* **Weight "e" for R >= 2 rings.** ``w_j ∝ 1 / e_j^2``. For two rings
  ``(1/e_1^2, 1/e_2^2) / (1/e_1^2 + 1/e_2^2) = (e_2^2, e_1^2) / (e_1^2 + e_2^2)``, which
  is Eq. 4.13 exactly; the other definitions multiply ``1/e_j^2`` by their factor:
  ``eZsource``: ``sin(Z_source_j)`` (Eq. 4.14); ``eZsurface``: ``sig(x_j)`` (Eq. 4.15);
  ``eZsourceZsurface``: both (Eq. 4.16 with sin Z2 in w2 -- the thesis's sin Z1 there
  is a typo).
* **Surface-zenith sigmoid.** ``sig(x) = 1 / (1 + exp(-10 (x - 0.5)))`` needs x in
  [0, 1]. With ``z = Z_surface_j / z_scale`` (``z_scale`` = 90 degrees by default,
  ``Z_surface_j`` the surface zenith of ring j's own estimated normal) the lowest-zenith
  ring uses ``x = z`` and the highest-zenith ring ``x = 1 - z``; a ring of zenith rank
  ``t`` (0 = lowest, 1 = highest) uses ``x = (1 - t) z + t (1 - z)`` (the middle ring of
  three gets sig(0.5) = 1/2 everywhere). Smooth regions (small Z_surface) thus favour
  the high-zenith ring (highlights hit the low ring there) and steep regions the low
  ring (shadows hit the high ring), as Fig. 4.11 describes; the crossover sits at
  ``Z_surface = z_scale / 2`` (45 degrees). Applying the *same* sig to both rings, as
  Eq. 4.15 literally reads, would cancel in the normalisation wherever the two ring
  normals agree, so the mirrored argument is the reading that gives the described
  behaviour.
* **binary** (Eq. 4.12): all weight on the ring with the largest weight (ties -> the
  first ring).
* **"oracle"** (Fig. 4.11e, the theoretical limit of WPS): needs ``truth_normals``.
  Any weighting yields a normal in the convex cone spanned by the ring normals (for
  two rings: on the great-circle arc between n_1 and n_2, Fig. 4.12). The oracle takes,
  per pixel, the direction of that cone closest to the true normal (exact: the truth
  itself when inside, else the best projection onto a face spanned by two ring
  normals, else the best ring normal) and reports the weights that produce it. It is
  therefore never worse, per pixel, than any other weighting, weighted or binary.
  With ``binary=True`` it picks the ring whose normal is closest to the truth.
* **"None"**: plain PS over the images of all rings (the "2Z PS" baseline of Table
  5.5); ``weights`` then hold each ring's share of the lights, n_j / k.
* Python ``None`` for ``weight`` means the default ``"eZsourceZsurface"`` (what
  :func:`psbench.solve` passes when no weight is given).

Rings are reported in ``Layout.rings()`` order (ring id order), which is the order of
the ring notation (``"30x8+60x8"``: ring 0 = 30 degrees).
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numpy as np

from .._checks import PsbenchError, as_images, as_mask, as_normals, choice
from . import kernel
from .api import Result

__all__ = ["wps", "WEIGHTS", "DEFAULT_WEIGHT", "sig", "surface_factor", "oracle_weights",
           "fuse"]

#: weight definitions (Section 4.3) plus the oracle limit and plain PS
WEIGHTS = ("None", "e", "eZsource", "eZsurface", "eZsourceZsurface", "oracle")
DEFAULT_WEIGHT = "eZsourceZsurface"
_EPS = np.float32(1e-30)


def sig(x):
    """The sigmoid of Eq. 4.15, ``1 / (1 + exp(-10 (x - 0.5)))``."""
    x = np.asarray(x, dtype=np.float32)
    return (1.0 / (1.0 + np.exp(np.float32(-10.0) * (x - np.float32(0.5))))).astype(np.float32)


def surface_factor(zenith_deg, rank, *, z_scale=90.0):
    """Surface-zenith weight factor of a ring (module docs).

    Parameters
    ----------
    zenith_deg : array_like
        Surface zenith of the ring's estimated normal, degrees.
    rank : float
        Zenith rank of the ring in [0, 1]: 0 = lowest source zenith, 1 = highest.
    z_scale : float
        Degrees mapped to x = 1 (default 90).
    """
    z = np.asarray(zenith_deg, dtype=np.float32) / np.float32(z_scale)
    t = np.float32(rank)
    return sig((1 - t) * z + t * (1 - z))


# --------------------------------------------------------------------------- Result
@dataclass(eq=False, repr=False)
class WPSResult(Result):
    """Output of :func:`psbench.solve.wps.wps`.

    The fields of :class:`psbench.solve.Result` (``normals (H, W, 3)``, ``albedo``,
    ``valid (k, H, W)``, ``residual (H, W)`` = L2 norm of the fused solution's residual
    over the used observations, ``height``, ``timings``, ``lights``, ``mask``,
    ``method = "wps"``) with ``weights`` of shape (rings, H, W) (sum 1 per pixel), plus
    ``ring_normals (rings, H, W, 3)``, ``ring_albedo (rings, H, W)``,
    ``ring_residual (rings, H, W)`` (RMS residual e_j of each ring's own solution),
    ``weight`` and ``binary``.
    """

    ring_normals: np.ndarray | None = None
    ring_albedo: np.ndarray | None = None
    ring_residual: np.ndarray | None = None
    weight: str = DEFAULT_WEIGHT
    binary: bool = False

    def __repr__(self):
        H, W = self.albedo.shape
        return (f"WPSResult(weight={self.weight!r}, binary={self.binary}, "
                f"mask={self.mask!r}, rings={self.weights.shape[0]}, size={H}x{W}, "
                f"total={self.timings.get('total', float('nan')):.3f}s)")


# --------------------------------------------------------------------------- helpers
def _layout(lights, k):
    from ..lights import Layout, layout
    try:
        lay = lights if isinstance(lights, Layout) else layout(lights)
    except PsbenchError:
        raise
    except Exception as exc:
        raise PsbenchError(f"lights must be a Layout, a (k, 3) array or ring notation like "
                           f"'30x8+60x8'; got {lights!r:.80} ({exc})") from None
    if lay.k != k:
        raise PsbenchError(f"lights has {lay.k} lights ({lay.name}) but images holds {k} images")
    return lay


def _rings(lay):
    rings = lay.rings()
    if len(rings) < 2:
        raise PsbenchError(
            f"lights={lay.name!r} has a single ring; WPS needs lights on at least two zenith "
            "rings, e.g. '30x8+60x8' (use method='ps' for one ring)")
    S = lay.S
    for j, idx in enumerate(rings):
        if idx.size < 3:
            raise PsbenchError(
                f"lights={lay.name!r}: ring {j} (zenith {lay.zenith[idx].mean():g}) has "
                f"{idx.size} light(s); every WPS ring needs at least 3")
        sv = np.linalg.svd(S[idx], compute_uv=False)
        if sv[-1] <= 1e-8 * sv[0]:
            raise PsbenchError(f"lights={lay.name!r}: ring {j}'s lights are degenerate "
                               "(coplanar with the origin); it cannot be solved on its own")
    return rings


def _ranks(lay, rings):
    zen = np.array([lay.zenith[idx].mean() for idx in rings])
    R = len(rings)
    order = np.argsort(zen, kind="stable")
    rank = np.empty(R)
    rank[order] = np.arange(R) / (R - 1)
    return zen, rank


def _arc_best(n1, n2, r):
    """Per-pixel best direction on the arc between unit n1 and n2 (3, N) w.r.t. r.

    Returns (c1, c2, cos): nonnegative coefficients of the direction c1 n1 + c2 n2
    (unnormalised) and its cosine with r.
    """
    a1 = (n1 * r).sum(0)
    a2 = (n2 * r).sum(0)
    c = (n1 * n2).sum(0)
    den = 1.0 - c * c
    ok = den > 1e-12
    den = np.where(ok, den, 1.0)
    al = (a1 - c * a2) / den
    be = (a2 - c * a1) / den
    inside = ok & (al >= 0) & (be >= 0) & ((al + be) > 0)
    p = al * n1 + be * n2
    pn = np.sqrt((p * p).sum(0))
    cos_in = np.where(inside, (p * r).sum(0) / np.where(inside, pn, 1.0), -2.0)
    # endpoints
    use1 = a1 >= a2
    c1 = np.where(inside, al, np.where(use1, 1.0, 0.0))
    c2 = np.where(inside, be, np.where(use1, 0.0, 1.0))
    cos = np.where(inside, cos_in, np.maximum(a1, a2))
    return c1, c2, cos


def oracle_weights(ring_b, truth, *, binary=False):
    """Oracle ring weights (module docs): best fusion direction per pixel.

    Parameters
    ----------
    ring_b : (R, 3, N) float
        Albedo-scaled ring normals.
    truth : (3, N) float
        True normals.
    binary : bool
        Pick the single ring closest to the truth.

    Returns
    -------
    w : (R, N) float32
        Nonnegative weights summing to 1 with ``sum_j w_j b_j`` along the best direction.
    """
    B = np.asarray(ring_b, dtype=np.float64)
    R, _, N = B.shape
    rho = np.sqrt((B * B).sum(1))  # (R, N)
    n = B / np.maximum(rho, 1e-30)[:, None]
    r = np.asarray(truth, dtype=np.float64)
    r = r / np.maximum(np.sqrt((r * r).sum(0)), 1e-30)
    # direction coefficients c (R, N) for n (not b): start with the best single ring
    cos_single = (n * r[None]).sum(1)  # (R, N)
    best = np.argmax(cos_single, axis=0)
    bestcos = np.take_along_axis(cos_single, best[None], 0)[0]
    C = np.zeros((R, N))
    C[best, np.arange(N)] = 1.0
    if not binary:
        for i, j in itertools.combinations(range(R), 2):
            c1, c2, cos = _arc_best(n[i], n[j], r)
            better = cos > bestcos
            if better.any():
                C[:, better] = 0.0
                C[i, better] = c1[better]
                C[j, better] = c2[better]
                bestcos = np.where(better, cos, bestcos)
        for tri in itertools.combinations(range(R), 3):
            M = np.stack([n[t] for t in tri], axis=-1)  # (3, N, 3): columns n_t
            Mt = np.moveaxis(M, 1, 0)  # (N, 3, 3)
            det = np.linalg.det(Mt)
            ok = np.abs(det) > 1e-9
            if not ok.any():
                continue
            coef = np.zeros((N, 3))
            coef[ok] = np.linalg.solve(Mt[ok], r.T[ok][..., None])[..., 0]
            inside = ok & (coef >= 0).all(axis=1) & (bestcos < 1.0)
            if inside.any():
                C[:, inside] = 0.0
                for q, t in enumerate(tri):
                    C[t, inside] = coef[inside, q]
                bestcos = np.where(inside, 1.0, bestcos)
    # direction coefficients -> b weights: sum_j w_j rho_j n_j ∝ sum_j c_j n_j
    w = C / np.maximum(rho, 1e-30)
    s = w.sum(0)
    w = np.where(s > 0, w / np.where(s > 0, s, 1.0), 1.0 / R)
    return w.astype(np.float32)


def fuse(ring_b, w):
    """Eq. 4.9: ``sum_j w_j b_j`` for ring_b (R, 3, N) and w (R, N) -> (3, N)."""
    out = ring_b[0] * w[0]
    for j in range(1, len(ring_b)):
        out += ring_b[j] * w[j]
    return out


def _dot3(a, b):
    """Row-wise dot product of two (3, N) arrays."""
    out = a[0] * b[0]
    out += a[1] * b[1]
    out += a[2] * b[2]
    return out


def _quad3(d, G):
    """d^T G d per column of a (3, N) array, symmetric 3x3 G."""
    G = np.asarray(G, dtype=np.float32)
    d0, d1, d2 = d
    out = (G[0, 0] * d0 + np.float32(2) * (G[0, 1] * d1 + G[0, 2] * d2)) * d0
    out += (G[1, 1] * d1 + np.float32(2) * G[1, 2] * d2) * d1
    out += G[2, 2] * d2 * d2
    return out


def _transpose(b, N):
    """(3, N) -> contiguous (N, 3)."""
    out = np.empty((N, 3), dtype=np.float32)
    for c in range(3):
        out[:, c] = b[c]
    return out


def _as_slice(idx):
    if idx.size and np.all(np.diff(idx) == 1):
        return slice(int(idx[0]), int(idx[-1]) + 1)
    return idx


# --------------------------------------------------------------------------- wps
def wps(images, lights, *, weight=DEFAULT_WEIGHT, binary=False, mask="None", object_mask=None,
        truth_normals=None, thresholds=None, seed=0, weighted=False, max_iter=10,
        want_height=False, z_scale=90.0, **opts):
    """Weighted multi-zenith PS (Section 4.3).

    Parameters
    ----------
    images : (k, H, W) array_like
    lights : Layout, ring notation or (k, 3) array_like
        At least two rings (ring ids of the Layout; explicit directions are grouped by
        zenith), each with at least 3 lights.
    weight : {"eZsourceZsurface", "eZsurface", "eZsource", "e", "oracle", "None"}
        Weight definition (module docs). None = the default.
    binary : bool
        Eq. 4.12: select the ring with the largest weight instead of blending.
    mask : str
        Mask applied to each ring's solve. "None" solves every ring with one
        least-squares product; anything else goes through :func:`psbench.solve.solve`
        on each ring's images and layout (with ``weighted``, ``thresholds``,
        ``max_iter``, ``seed`` and ``opts``).
    object_mask : (H, W) bool, optional
        Outside: normals (0, 0, 1), albedo 0, residual 0 (weights are still reported).
    truth_normals : (H, W, 3) array_like, optional
        Needed by ``weight="oracle"``.
    thresholds : dict, optional
        Passed to the ring solves (masks only).
    seed : int
        Passed to the ring solves (RA).
    want_height : bool
        Integrate the fused normals (Poisson) into ``height``.
    z_scale : float
        Degrees of surface zenith mapped to 1 in the sigmoid argument (default 90).
    **opts
        Extra options for the masked ring solves (see :func:`psbench.solve.solve`).

    Returns
    -------
    WPSResult
        ``Result`` fields with ``method="wps"``, ``weights (rings, H, W)``,
        ``ring_normals (rings, H, W, 3)``, ``ring_albedo (rings, H, W)``,
        ``ring_residual (rings, H, W)`` (RMS e_j), ``timings``.

    Notes
    -----
    Without a mask everything comes from one product ``I^T M``: M stacks the rings'
    pseudo-inverses (b_j) and orthonormal bases U_j of null(S_j^T), so that
    ``|I_j - S_j b_j| = |U_j^T I_j|`` exactly; the fused residual follows without
    another pass over the images from Pythagoras,
    ``|I_j - S_j b|^2 = |I_j - S_j b_j|^2 + (b_j - b)^T S_j^T S_j (b_j - b)``.
    """
    t0 = time.perf_counter()
    tm = {}
    images = as_images(images, min_count=3)
    k, H, W = images.shape
    N = H * W
    lay = _layout(lights, k)
    weight = DEFAULT_WEIGHT if weight is None else weight
    weight = choice(weight, WEIGHTS, "weight")
    if not isinstance(binary, (bool, np.bool_)):
        raise PsbenchError(f"binary must be True or False, got {binary!r}")
    if not (np.isscalar(z_scale) and float(z_scale) > 0):
        raise PsbenchError(f"z_scale must be a number of degrees > 0, got {z_scale!r}")
    rings = _rings(lay)
    R = len(rings)
    if mask is None:
        mask = "None"
    if not isinstance(mask, str):
        raise PsbenchError(f"mask must be a string like 'Th-Hi-Re-Sh', got {type(mask).__name__}")
    plain = mask.strip().lower() == "none" and not weighted
    if not plain:
        from .api import parse_mask
        tokens = parse_mask(mask)
        mask_name = "-".join(tokens) if tokens else "None"
    else:
        mask_name = "None"
    if plain and opts:
        from .api import OPTIONS
        bad = [o for o in opts if o not in OPTIONS and o != "th_scope"]
        if bad:
            raise PsbenchError(f"wps() got unknown option(s) {', '.join(map(repr, bad))}")
    full = object_mask is None
    omask = as_mask(object_mask, (H, W), "object_mask")
    if not omask.any():
        raise PsbenchError("object_mask selects no pixel")
    full = full or bool(omask.all())
    truth = None
    if truth_normals is not None:
        truth = as_normals(truth_normals, "truth_normals", (H, W))
    if weight == "oracle" and truth is None:
        raise PsbenchError("weight='oracle' needs truth_normals (H, W, 3): the oracle weights "
                           "come from the true normal error of each ring")
    S = lay.S.astype(np.float64)
    I2 = images.reshape(k, N)
    zen, rank = _ranks(lay, rings)
    tm["validate"] = time.perf_counter() - t0
    t = time.perf_counter()

    # ---- ring solves (Eqs. 4.3-4.8) ----------------------------------------------------
    info = {"ring_zeniths": zen.tolist()}
    iterations = 0
    thr_used = {}
    G = [S[idx].T @ S[idx] for idx in rings]  # S_j^T S_j
    if plain:
        # one product gives every ring's b (pseudo-inverse rows) and the coordinates of
        # its residual in an orthonormal basis of null(S_j^T) (exact |I_j - S_j b_j|)
        dof = [idx.size - 3 for idx in rings]
        M = np.zeros((k, 3 * R + sum(dof)))
        col = 3 * R
        for j, idx in enumerate(rings):
            M[idx, 3 * j:3 * j + 3] = np.linalg.pinv(S[idx]).T
            if dof[j]:
                U = np.linalg.svd(S[idx], full_matrices=True)[0]
                M[idx, col:col + dof[j]] = U[:, 3:]
            col += dof[j]
        X = M.T.astype(np.float32) @ I2  # (3R + sum dof, N), rows contiguous
        ring_b = [X[3 * j:3 * j + 3] for j in range(R)]
        e2 = np.zeros((R, N), dtype=np.float32)
        col = 3 * R
        for j, idx in enumerate(rings):
            if dof[j]:
                Xj = X[col:col + dof[j]]
                np.einsum("ij,ij->j", Xj, Xj, out=e2[j])
                e2[j] *= np.float32(1.0 / idx.size)
            col += dof[j]
        valid = None
    else:
        from .api import solve
        X = np.empty((3 * R, N), dtype=np.float32)
        e2 = np.empty((R, N), dtype=np.float32)
        valid = np.ones((k, H, W), dtype=bool)
        ring_info = []
        for j, idx in enumerate(rings):
            rj = solve(images[idx], lay.subset(idx), mask=mask, weighted=weighted,
                       object_mask=object_mask, thresholds=thresholds, max_iter=max_iter,
                       seed=seed, truth_normals=truth, **opts)
            bj = rj.normals * rj.albedo[..., None]
            X[3 * j:3 * j + 3] = bj.reshape(N, 3).T
            vj = rj.valid
            valid[idx] = vj
            r2 = (images[idx] - kernel.lambert(bj, S[idx])) ** 2
            if rj.weights is not None:
                wj = np.asarray(rj.weights, dtype=np.float32)
                e2[j] = ((r2 * wj).sum(0) / np.maximum(wj.sum(0), 1e-12)).reshape(N)
            else:
                e2[j] = ((r2 * vj).sum(0) / np.maximum(vj.sum(0), 1)).reshape(N)
            iterations = max(iterations, rj.iterations)
            thr_used[f"ring{j}"] = rj.thresholds
            ring_info.append(rj.info)
        ring_b = [X[3 * j:3 * j + 3] for j in range(R)]
        info["rings"] = ring_info
    rho = np.empty((R, N), dtype=np.float32)
    for j in range(R):
        np.sqrt(_dot3(ring_b[j], ring_b[j]), out=rho[j])
    tm["rings"] = time.perf_counter() - t
    t = time.perf_counter()

    # ---- weights (Eqs. 4.10-4.16) -------------------------------------------------------
    if weight == "None":
        w = np.empty((R, N), dtype=np.float32)
        for j, idx in enumerate(rings):
            w[j] = idx.size / k
    elif weight == "oracle":
        w = oracle_weights(np.stack(ring_b), truth.reshape(N, 3).T, binary=binary)
    else:
        u = np.empty((R, N), dtype=np.float32)
        for j in range(R):
            uj = u[j]
            np.add(e2[j], _EPS, out=uj)
            np.divide(np.float32(1.0), uj, out=uj)
            if weight in ("eZsource", "eZsourceZsurface"):
                uj *= np.float32(np.sin(np.radians(zen[j])))
            if weight in ("eZsurface", "eZsourceZsurface"):
                nz = ring_b[j][2] / np.maximum(rho[j], np.float32(1e-30))
                np.clip(nz, -1.0, 1.0, out=nz)
                zs = np.arccos(nz, out=nz)
                zs *= np.float32(180.0 / np.pi)
                uj *= surface_factor(zs, rank[j], z_scale=z_scale)
        if binary:
            pick = np.argmax(u, axis=0)
            w = np.zeros((R, N), dtype=np.float32)
            w[pick, np.arange(N)] = 1.0
        else:
            w = u
            w /= u.sum(axis=0)
    tm["weights"] = time.perf_counter() - t
    t = time.perf_counter()

    # ---- fuse (Eq. 4.9) -----------------------------------------------------------------
    if weight == "None":
        if plain:
            b = kernel.ls(images, S).reshape(N, 3)
        else:
            from .api import solve
            r0 = solve(images, lay, mask=mask, weighted=weighted, object_mask=object_mask,
                       thresholds=thresholds, max_iter=max_iter, seed=seed, **opts)
            b = (r0.normals * r0.albedo[..., None]).reshape(N, 3)
            valid = r0.valid
    else:
        bf = fuse(ring_b, w)  # (3, N)
        b = _transpose(bf, N)
    normals, albedo = kernel.split(b.reshape(H, W, 3))
    tm["fuse"] = time.perf_counter() - t
    t = time.perf_counter()

    # ---- residual of the fused solution -----------------------------------------------
    if plain:
        # Pythagoras per ring: |I_j - S_j b|^2 = |I_j - S_j b_j|^2 + (b_j - b)^T G_j (b_j - b)
        bo = bf if weight != "None" else b.T  # fused rho n, (3, N)
        r2 = np.zeros(N, dtype=np.float32)
        for j, idx in enumerate(rings):
            d = ring_b[j] - bo
            r2 += _quad3(d, G[j])
            r2 += e2[j] * np.float32(idx.size)
        resid = np.sqrt(r2).reshape(H, W)
        valid = np.ones((k, H, W), dtype=bool)
    else:
        b_out = normals * albedo[..., None]
        resid = _residual(I2, b_out.reshape(N, 3), S.astype(np.float32),
                          None if valid.all() else valid).reshape(H, W)
    tm["residual"] = time.perf_counter() - t
    t = time.perf_counter()

    ring_normals = np.empty((R, N, 3), dtype=np.float32)
    for j in range(R):
        inv = np.float32(1.0) / np.maximum(rho[j], np.float32(1e-30))
        for c in range(3):
            np.multiply(ring_b[j][c], inv, out=ring_normals[j][:, c])
        zero = rho[j] <= 1e-6
        if zero.any():
            ring_normals[j][zero] = (0.0, 0.0, 1.0)
    ring_normals = ring_normals.reshape(R, H, W, 3)
    ring_albedo = rho.reshape(R, H, W)
    ring_residual = np.sqrt(e2).reshape(R, H, W)
    weights = w.reshape(R, H, W)
    if not full:
        out = ~omask
        normals[out] = (0.0, 0.0, 1.0)
        albedo[out] = 0.0
        resid[out] = 0.0
        valid[:, out] = True
    height = None
    if want_height:
        from ..integrate import integrate
        height = np.asarray(integrate(normals, None if full else omask), dtype=np.float32)
    tm["outputs"] = time.perf_counter() - t
    tm["total"] = time.perf_counter() - t0
    cls = WPSResult
    return cls(normals=normals, albedo=albedo, valid=valid, weights=weights, residual=resid,
               height=height, timings=tm, lights=lay, mask=mask_name, method="wps",
               iterations=int(iterations), thresholds=thr_used, info=info,
               ring_normals=ring_normals, ring_albedo=ring_albedo, ring_residual=ring_residual,
               weight=weight, binary=bool(binary))


def _residual(I2, B, S32, valid):
    """sqrt(sum_i valid_i (i - s_i . b)^2) per pixel, (N,) float32, chunked."""
    k, N = I2.shape
    out = np.empty(N, dtype=np.float32)
    step = 1 << 16
    for lo in range(0, N, step):
        hi = min(N, lo + step)
        r = I2[:, lo:hi] - S32 @ B[lo:hi].T
        r *= r
        if valid is not None:
            r *= valid.reshape(k, -1)[:, lo:hi]
        out[lo:hi] = r.sum(axis=0)
    np.sqrt(out, out=out)
    return out
