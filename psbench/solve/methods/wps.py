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
  5.5); ``ring_weights`` then hold each ring's share of the lights, n_j / k.
* Python ``None`` for ``weight`` means the default ``"eZsourceZsurface"`` (what
  :func:`psbench.solve` passes when no weight is given).
* **Masks.** WPS is registered with ``masked=False``: each ring is solved by the mask
  engine on its own images and layout (``Problem.engine``: thresholds resolved for the
  ring's image count, ``weighted`` applied per ring). ``mask="None"`` without
  ``weighted`` solves every ring with one least-squares product.

Rings are reported in ``Layout.rings()`` order (ring id order), which is the order of
the ring notation (``"30x8+60x8"``: ring 0 = 30 degrees).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ..._checks import PsbenchError, choice
from ...registry import Method
from .. import kernel
from .._result import Result
from ..base import Fit, Options
from ._wps_weights import (DEFAULT_WEIGHT, WEIGHTS, _dot3, _quad3, _transpose, fuse,
                           oracle_weights, surface_factor)

__all__ = ["WPSOptions", "WPSResult", "wps", "METHOD"]

_EPS = np.float32(1e-30)


@dataclass
class WPSOptions(Options):
    """Options of "wps": the mask engine's (:class:`psbench.solve.base.Options`, used by
    every ring's solve) plus

    Parameters
    ----------
    weight : {"eZsourceZsurface", "eZsurface", "eZsource", "e", "oracle", "None"}
        Weight definition (module docs); None = the default "eZsourceZsurface".
    binary : bool
        Eq. 4.12: select the ring with the largest weight instead of blending.
    z_scale : float
        Degrees of surface zenith mapped to 1 in the sigmoid argument; > 0, default 90.
    """

    weight: str | None = DEFAULT_WEIGHT
    binary: bool = False
    z_scale: float = 90.0

    def __post_init__(self):
        super().__post_init__()
        if self.weight is None:
            self.weight = DEFAULT_WEIGHT
        choice(self.weight, WEIGHTS, "weight")
        if not isinstance(self.binary, (bool, np.bool_)):
            raise PsbenchError(f"binary must be True or False, got {self.binary!r}")
        if not (np.isscalar(self.z_scale) and not isinstance(self.z_scale, (bool, str))
                and float(self.z_scale) > 0):
            raise PsbenchError(f"z_scale must be a number of degrees > 0, got {self.z_scale!r}")


@dataclass(eq=False, repr=False)
class WPSResult(Result):
    """Output of ``solve(..., method="wps")``.

    The fields of :class:`psbench.solve.Result` (``normals (H, W, 3)``, ``albedo``,
    ``valid (k, H, W)``, ``residual (H, W)`` = L2 norm of the fused solution's residual
    over the used observations, ``height``, ``timings``, ``lights``, ``mask``,
    ``method = "wps"``, ``weights`` (k, H, W) per observation from the rings' weighted
    solves or None) with ``ring_weights`` of shape (rings, H, W) (sum 1 per pixel),
    plus ``ring_normals (rings, H, W, 3)``, ``ring_albedo (rings, H, W)``,
    ``ring_residual (rings, H, W)`` (RMS residual e_j of each ring's own solution),
    ``weight`` and ``binary``. ``thresholds`` maps "ring0", "ring1", ... to each ring's
    resolved thresholds (empty without masks).
    """

    ring_normals: np.ndarray | None = None
    ring_albedo: np.ndarray | None = None
    ring_residual: np.ndarray | None = None
    weight: str = DEFAULT_WEIGHT
    binary: bool = False

    def __repr__(self):
        H, W = self.albedo.shape
        return (f"WPSResult(weight={self.weight!r}, binary={self.binary}, "
                f"mask={self.mask!r}, rings={self.ring_weights.shape[0]}, size={H}x{W}, "
                f"total={self.timings.get('total', float('nan')):.3f}s)")


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


def _plain_rings(I2, S, rings, k):
    """Every ring's b and mean squared residual from one product ``M^T I``: M stacks the
    rings' pseudo-inverses and orthonormal bases U_j of null(S_j^T), so that
    ``|I_j - S_j b_j| = |U_j^T I_j|`` exactly."""
    R, N = len(rings), I2.shape[1]
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
    e2 = np.zeros((R, N), dtype=np.float32)
    col = 3 * R
    for j, idx in enumerate(rings):
        if dof[j]:
            Xj = X[col:col + dof[j]]
            np.einsum("ij,ij->j", Xj, Xj, out=e2[j])
            e2[j] *= np.float32(1.0 / idx.size)
        col += dof[j]
    return [X[3 * j:3 * j + 3] for j in range(R)], e2


def _masked_rings(problem, rings, S, N):
    """Each ring through the mask engine; e_j^2 over the observations it used."""
    images, lay = problem.images, problem.lights
    k, H, W = images.shape
    R = len(rings)
    X = np.empty((3 * R, N), dtype=np.float32)
    e2 = np.empty((R, N), dtype=np.float32)
    valid = np.ones((k, H, W), dtype=bool)
    obs_w = None
    iterations, converged, thr, infos = 0, True, {}, []
    for j, idx in enumerate(rings):
        rj = problem.engine(images[idx], lay.subset(idx), truth_normals=problem.truth_normals)
        bj = rj.normals * rj.albedo[..., None]
        X[3 * j:3 * j + 3] = bj.reshape(N, 3).T
        vj = rj.valid
        valid[idx] = vj
        r2 = (images[idx] - kernel.lambert(bj, S[idx])) ** 2
        if rj.weights is not None:
            wj = np.asarray(rj.weights, dtype=np.float32)
            e2[j] = ((r2 * wj).sum(0) / np.maximum(wj.sum(0), 1e-12)).reshape(N)
            if obs_w is None:
                obs_w = np.zeros((k, H, W), dtype=np.float32)
            obs_w[idx] = wj
        else:
            e2[j] = ((r2 * vj).sum(0) / np.maximum(vj.sum(0), 1)).reshape(N)
        iterations = max(iterations, rj.iterations)
        converged = converged and rj.converged is not False
        thr[f"ring{j}"] = rj.thresholds
        infos.append(rj.info)
    ring_b = [X[3 * j:3 * j + 3] for j in range(R)]
    return ring_b, e2, valid, obs_w, iterations, converged, thr, infos


def _weights(weight, binary, ring_b, e2, rho, rings, k, zen, rank, z_scale, truth, N):
    """Eqs. 4.10-4.16 (module docs) -> (R, N) float32."""
    R = len(rings)
    if weight == "None":
        w = np.empty((R, N), dtype=np.float32)
        for j, idx in enumerate(rings):
            w[j] = idx.size / k
        return w
    if weight == "oracle":
        return oracle_weights(np.stack(ring_b), truth.reshape(N, 3).T, binary=binary)
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
        return _one_hot_max(u)
    u /= u.sum(axis=0)
    return u


def _one_hot_max(u):
    """(R, N) -> float32 one-hot of the first maximum per column (``argmax``), ring by
    ring: numpy's argmax over a short first axis is strided and ~30x slower."""
    R, N = u.shape
    best = u[0].copy()
    pick = np.zeros(N, dtype=np.int16)
    for j in range(1, R):
        gt = u[j] > best                  # strict: ties keep the earlier ring, as argmax
        pick[gt] = j
        np.maximum(best, u[j], out=best)
    w = np.empty((R, N), dtype=np.float32)
    for j in range(R):
        np.equal(pick, j, out=w[j], casting="unsafe")
    return w


def wps(problem, options):
    """Weighted multi-zenith PS (Section 4.3): solve each ring, weight, fuse (Eq. 4.9).

    Without a mask everything comes from one product ``I^T M`` (:func:`_plain_rings`);
    the fused residual then follows without another pass over the images from
    Pythagoras, ``|I_j - S_j b|^2 = |I_j - S_j b_j|^2 + (b_j - b)^T S_j^T S_j (b_j - b)``.
    """
    images, lay, truth = problem.images, problem.lights, problem.truth_normals
    weight, binary = options.weight, bool(options.binary)
    if weight == "oracle" and truth is None:
        raise PsbenchError("weight='oracle' needs truth_normals (H, W, 3): the oracle weights "
                           "come from the true normal error of each ring")
    rings = _rings(lay)
    k, H, W = images.shape
    N, R = H * W, len(rings)
    S = lay.S.astype(np.float64)
    I2 = images.reshape(k, N)
    zen, rank = _ranks(lay, rings)
    tm = {}
    t = time.perf_counter()
    plain = problem.mask == "None" and not options.weighted
    info = {"ring_zeniths": zen.tolist()}
    iterations, converged, thr, obs_w, valid = 0, True, {}, None, None
    if plain:
        ring_b, e2 = _plain_rings(I2, S, rings, k)
    else:
        ring_b, e2, valid, obs_w, iterations, converged, thr, info["rings"] = _masked_rings(
            problem, rings, S, N)
    rho = np.empty((R, N), dtype=np.float32)
    for j in range(R):
        np.sqrt(_dot3(ring_b[j], ring_b[j]), out=rho[j])
    tm["rings"] = time.perf_counter() - t
    t = time.perf_counter()
    w = _weights(weight, binary, ring_b, e2, rho, rings, k, zen, rank, options.z_scale, truth, N)
    tm["weights"] = time.perf_counter() - t
    t = time.perf_counter()
    if weight != "None":
        bf = fuse(ring_b, w)  # (3, N)
        b = _transpose(bf, N)
    elif plain:
        # least squares over every image from the ring solutions, without another pass
        # over the images: S^T I = sum_j G_j b_j with G_j = S_j^T S_j (full-rank rings)
        G = [S[idx].T @ S[idx] for idx in rings]
        A = np.linalg.inv(sum(G))
        bf = sum((A @ G[j]).astype(np.float32) @ ring_b[j] for j in range(R))
        b = _transpose(bf, N)
    else:  # "2Z PS" with the mask: one masked solve over every image
        r0 = problem.engine(images, lay)
        b = (r0.normals * r0.albedo[..., None]).reshape(N, 3)
        valid, obs_w = r0.valid, r0.weights
    tm["fuse"] = time.perf_counter() - t
    t = time.perf_counter()
    if plain:
        # Pythagoras per ring: |I_j - S_j b|^2 = |I_j - S_j b_j|^2 + (b_j - b)^T G_j (b_j - b)
        bo = bf  # fused rho n, (3, N)
        r2 = np.zeros(N, dtype=np.float32)
        for j, idx in enumerate(rings):
            r2 += _quad3(ring_b[j] - bo, S[idx].T @ S[idx])
            r2 += e2[j] * np.float32(idx.size)
        resid = np.sqrt(r2).reshape(H, W)
        valid = np.ones((k, H, W), dtype=bool)
    else:
        normals, albedo = kernel.split(b.reshape(H, W, 3))
        resid = kernel.residual_norm(images, normals * albedo[..., None], S,
                                     None if valid.all() else valid)
    tm["residual"] = time.perf_counter() - t
    ring_normals = np.empty((R, N, 3), dtype=np.float32)
    for j in range(R):
        inv = np.float32(1.0) / np.maximum(rho[j], np.float32(1e-30))
        for c in range(3):
            np.multiply(ring_b[j][c], inv, out=ring_normals[j][:, c])
        zero = rho[j] <= 1e-6
        if zero.any():
            ring_normals[j][zero] = (0.0, 0.0, 1.0)
    fields = dict(ring_normals=ring_normals.reshape(R, H, W, 3), ring_albedo=rho.reshape(R, H, W),
                  ring_residual=np.sqrt(e2).reshape(R, H, W), weight=weight, binary=binary,
                  thresholds=thr)
    return Fit(b=b.reshape(H, W, 3), valid=valid, weights=obs_w, iterations=iterations,
               converged=converged, info=info, residual=resid, ring_weights=w.reshape(R, H, W),
               timings=tm, fields=fields, result_type=WPSResult)


METHOD = Method("wps", wps, options=WPSOptions, masked=False,
                help="weighted multi-zenith PS: one masked solve per ring, fused (Section 4.3)")
