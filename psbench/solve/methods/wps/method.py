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
  ``weighted`` solves every ring, measures its residual, weighs and fuses in one
  compiled pass over the images (:mod:`psbench.solve.methods.wps._kernel`); the ring
  normals, albedo and residual are then computed when first read (the same compiled
  ring solves again, bit-identical), as the plain PS residual is.
* **Saturation** is not treated, as in the thesis: where every image of a ring is
  clipped at a pixel, the ring's observations are constant, its fit is the flat
  normal with zero residual, and the residual weights give it the whole weight. On
  breech faces imaged with the 31° ring overexposed this flattens most of the face
  (measured in the forensic guide).

Rings are reported in ``Layout.rings()`` order (ring id order), which is the order of
the ring notation (``"30x8+60x8"``: ring 0 = 30 degrees).
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numpy as np

from ...._shared.checks import PsbenchError, choice
from ....registry import Method
from ... import kernel
from ..._result import Result
from ...base import Fit, Lazy, Options
from . import _kernel as _k
from ._weights import DEFAULT_WEIGHT, WEIGHTS

__all__ = ["WPSOptions", "WPSResult", "wps", "METHOD"]

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
    ``weight`` and ``binary`` (without a mask the three ring outputs are computed when
    first read, from the images given to the solve). ``thresholds`` maps "ring0",
    "ring1", ... to each ring's resolved thresholds (empty without masks).
    """

    ring_normals: np.ndarray | None = Lazy(None)
    ring_albedo: np.ndarray | None = Lazy(None)
    ring_residual: np.ndarray | None = Lazy(None)
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


def _ring_setup(lay, rings, options, truth, N):
    """The kernels' constants: weight kind and factors, ring pairs / triples (oracle)."""
    weight, R = options.weight, len(rings)
    zen, rank = _ranks(lay, rings)
    kind = {"None": _k.KIND_NONE, "oracle": _k.KIND_ORACLE}.get(weight, _k.KIND_E)
    # float32 values held as float64, like every other factor: one array type per
    # argument means one compilation of the kernel (ring_solutions passes float64)
    share = np.array([np.float32(idx.size / lay.S.shape[0]) for idx in rings],
                     dtype=np.float64)
    sinz = np.array([np.float32(np.sin(np.radians(z))) for z in zen], dtype=np.float64)
    # writable C float32 either way: numba compiles read-only arrays separately
    T = (np.require(truth.reshape(N, 3), np.float32, ["C", "W"]) if kind == _k.KIND_ORACLE
         else np.zeros((1, 3), dtype=np.float32))
    pairs = np.array(list(itertools.combinations(range(R), 2)), dtype=np.int64).reshape(-1, 2)
    tris = np.array(list(itertools.combinations(range(R), 3)), dtype=np.int64).reshape(-1, 3)
    args = (kind, share, weight in ("eZsource", "eZsourceZsurface"),
            weight in ("eZsurface", "eZsourceZsurface"), sinz, rank.astype(np.float64),
            1.0 / float(options.z_scale), bool(options.binary), T, pairs, tris)
    return zen, args


def _outputs(R, N):
    return (np.empty((N, 3), dtype=np.float32), np.empty((R, N), dtype=np.float32),
            np.empty((R, N, 3), dtype=np.float32), np.empty((R, N), dtype=np.float32),
            np.empty((R, N), dtype=np.float32))


def _constants(S, rings):
    """The ring solves' constants of :func:`psbench.solve.methods.wps._kernel.plain_rings`:
    order, start, P, F, G, count."""
    k, R = S.shape[0], len(rings)
    order = np.concatenate(rings).astype(np.int64)
    start = np.cumsum([0] + [idx.size for idx in rings]).astype(np.int64)
    P = np.empty((k, 3))
    G = np.empty((R, 3, 3))
    for j, idx in enumerate(rings):
        P[idx] = np.linalg.pinv(S[idx]).T
        G[j] = S[idx].T @ S[idx]
    # weight "None": least squares over every image from the ring solutions,
    # S^T I = sum_j G_j b_j (full-rank rings), so b = sum_j (A G_j) b_j, A = (S^T S)^-1
    A = np.linalg.inv(G.sum(0))
    F = np.einsum("ab,jbc->jac", A, G)
    return order, start, P, F, G, np.diff(start)


def _plain(I2, S, rings, args):
    """Every ring's solve, residual, weights and the fusion in one pass over the images
    (:func:`psbench.solve.methods.wps._kernel.plain_rings`); the ring outputs follow
    on demand (:class:`_RingOutputs`)."""
    N, R = I2.shape[1], len(rings)
    order, start, P, F, G, count = _constants(S, rings)
    I2 = np.ascontiguousarray(I2)
    b = np.empty((N, 3), dtype=np.float32)
    w = np.empty((R, N), dtype=np.float32)
    resid = np.empty(N, dtype=np.float32)
    _k.plain_rings(I2, order, start, P, F, G, count, *args, b, resid, w)
    return b, resid, w, _RingOutputs(I2, order, start, P, G, count)


class _RingOutputs:
    """The ring normals, albedo and RMS residual of the unmasked path, computed when
    first read: most callers read only the fused result and ``ring_weights``, and
    writing the ring outputs would cost a fifth of the solve. The second pass runs
    the same compiled ring solves, so the values are bit-identical to a pass that
    writes everything; like the plain PS residual, they are computed from the images
    given to the solve."""

    def __init__(self, I2, *consts):
        self._args = (I2, *consts)
        self._out = None

    def __call__(self, i):
        if self._out is None:
            I2, order, start, P, G, count = self._args
            R, N = count.shape[0], I2.shape[1]
            ring_normals = np.empty((R, N, 3), dtype=np.float32)
            ring_albedo = np.empty((R, N), dtype=np.float32)
            ring_e = np.empty((R, N), dtype=np.float32)
            _k.ring_solutions(I2, order, start, P, G, count, ring_normals, ring_albedo,
                              ring_e)
            self._out = (ring_normals, ring_albedo, ring_e)
            self._args = None   # the images are no longer needed
        return self._out[i]


def _masked_rings(problem, rings, S, N):
    """Each ring through the mask engine; e_j^2 over the observations it used."""
    images, lay = problem.images, problem.lights
    k, H, W = images.shape
    R = len(rings)
    X = np.empty((R, 3, N), dtype=np.float32)
    e2 = np.empty((R, N), dtype=np.float32)
    valid = np.ones((k, H, W), dtype=bool)
    obs_w = None
    iterations, converged, thr, infos = 0, True, {}, []
    for j, idx in enumerate(rings):
        rj = problem.engine(images[idx], lay.subset(idx), truth_normals=problem.truth_normals)
        bj = rj.normals * rj.albedo[..., None]
        X[j] = bj.reshape(N, 3).T
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
    return X, e2, valid, obs_w, iterations, converged, thr, infos


def wps(problem, options):
    """Weighted multi-zenith PS (Section 4.3): solve each ring, weight, fuse (Eq. 4.9).

    Without a mask one compiled pass over the images does everything
    (:func:`_plain`); the fused residual then follows from Pythagoras,
    ``|I_j - S_j b|^2 = |I_j - S_j b_j|^2 + (b_j - b)^T S_j^T S_j (b_j - b)``. With a
    mask the rings come from the mask engine and only the weights and the fusion are
    compiled (:func:`psbench.solve.methods.wps._kernel.weigh_rings`).
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
    zen, args = _ring_setup(lay, rings, options, truth, N)
    tm = {}
    t = time.perf_counter()
    plain = problem.mask == "None" and not options.weighted
    info = {"ring_zeniths": zen.tolist()}
    iterations, converged, thr, obs_w = 0, True, {}, None
    if plain:
        b, resid, w, lazy = _plain(images.reshape(k, N), S, rings, args)
        resid = resid.reshape(H, W)
        ring_normals = lambda: lazy(0).reshape(R, H, W, 3)  # noqa: E731
        ring_albedo = lambda: lazy(1).reshape(R, H, W)      # noqa: E731
        ring_e = lambda: lazy(2).reshape(R, H, W)           # noqa: E731
        valid = np.ones((k, H, W), dtype=bool)
        tm["rings"] = time.perf_counter() - t
    else:
        ring_b, e2, valid, obs_w, iterations, converged, thr, info["rings"] = _masked_rings(
            problem, rings, S, N)
        tm["rings"] = time.perf_counter() - t
        t = time.perf_counter()
        b, w, ring_normals, ring_albedo, ring_e = _outputs(R, N)
        _k.weigh_rings(ring_b, e2, *args, b, w, ring_normals, ring_albedo, ring_e)
        if weight == "None":  # "2Z PS" with the mask: one masked solve over every image
            r0 = problem.engine(images, lay)
            b = (r0.normals * r0.albedo[..., None]).reshape(N, 3)
            valid, obs_w = r0.valid, r0.weights
        tm["weights"] = time.perf_counter() - t
        t = time.perf_counter()
        normals, albedo = kernel.split(b.reshape(H, W, 3))
        resid = kernel.residual_norm(images, normals * albedo[..., None], S,
                                     None if valid.all() else valid)
        tm["residual"] = time.perf_counter() - t
        ring_normals = ring_normals.reshape(R, H, W, 3)
        ring_albedo, ring_e = ring_albedo.reshape(R, H, W), ring_e.reshape(R, H, W)
    fields = dict(ring_normals=ring_normals, ring_albedo=ring_albedo, ring_residual=ring_e,
                  weight=weight, binary=binary, thresholds=thr)
    return Fit(b=b.reshape(H, W, 3), valid=valid, weights=obs_w, iterations=iterations,
               converged=converged, info=info, residual=resid, ring_weights=w.reshape(R, H, W),
               timings=tm, fields=fields, result_type=WPSResult)


METHOD = Method("wps", wps, options=WPSOptions, masked=False,
                help="weighted multi-zenith PS: one masked solve per ring, fused (Section 4.3)")
