"""The Chapter 7 evaluation as pure functions returning tidy tables.

For a set of cartridge cases (``gun`` x ``case`` seeds) and a set of PS methods and
integrators, :func:`evaluate` renders each case with the Chapter 7 acquisition
(:func:`psbench.forensic.presets.acquire`), solves it with every method
(:func:`psbench.solve`), integrates the normals with every integrator, and measures

- NE (mean angular error, degrees) over the case, the breech face and the firing pin;
- height errors in µm over the firing pin (offset removed), its walls (offset removed)
  and the breech face (best plane removed);
- the solve and integration times;
- the identification: CCFmax (:func:`psbench.forensic.identify.register` on band-passed
  heights) of every pair of cases, sister pairs (same gun) and non-sister pairs, per
  comparison region, and per method/integrator the separation (smallest sister score
  minus largest non-sister score), the area under the ROC curve and how often the
  registration found the true rotation.

Two references are scored beside the methods: the ground-truth heights
(:data:`TRUTH`) and the integrated ground-truth normals (:data:`TRUTH_NORMALS`, what a
perfect PS would give after integration). On coarse images the latter is the better
upper bound: integration of central-difference normals attenuates the shortest
wavelengths, where the case's own texture (not shared by sisters) weighs most.

The comparison regions are each case's ground-truth regions (``breech_face``, the
field's comparison, and ``firing_pin``, the impression): the segmentation is not what
is under test here. :func:`plane_study` measures the sample-plane correction.
"""
from __future__ import annotations

import itertools
import time
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ..integrate.bilateral import bilateral_integrate
from .. import registry
from .._shared.checks import PsbenchError
from .._shared.deprecation import renamed_names
from ..integrate.poisson import integrate
from ..metrics.errors import normal_error
from ..solve import solve
from .cartridge import DEFAULT_PIXEL_SIZE, make_cartridge
from .identify import LONG_CUTOFF, bandpass, register
from .plane import Plane, estimate_plane, level, level_sample, tilt_surface
from .presets import acquire

__all__ = ["RECIPES", "recipes", "INTEGRATORS", "TRUTH", "TRUTH_NORMALS", "Reconstruction",
           "reconstruct",
           "solve_kwargs", "roughness", "height_error", "score_pairs", "separation", "auc",
           "evaluate", "plane_study", "warm_up_integrators"]

#: psbench's recipes: method label -> keyword arguments of :func:`psbench.solve`
#: (``weights_um``: see :func:`solve_kwargs`). The thesis's four (Figs. 7.8-7.9), its
#: FWLSE (Section 3.4.1), and psbench's robust estimators. Registered in the
#: ``psbench.recipes`` group of :mod:`psbench.registry`, where plug-ins add theirs
#: (:class:`psbench.registry.Recipe`); :func:`recipes` lists them all.
RECIPES = {
    "None": {"mask": "None"},
    "Th-Hi-Re-Sh": {"mask": "Th-Hi-Re-Sh"},
    "weighted Th-Hi-Re-Sh": {"mask": "Th-Hi-Re-Sh", "weighted": True},
    "weighted Th-Hi-Re-Sh (um)": {"mask": "Th-Hi-Re-Sh", "weighted": True, "weights_um": True},
    "WPS": {"method": "wps"},
    "FWLSE": {"method": "fwlse"},
    "robust": {"method": "robust"},
    "tsfit": {"method": "tsfit"},
    "tukey": {"method": "tukey"},
    "l1": {"method": "l1"},
}
#: the weighted masks' pixel parameters (Options defaults: dilation radius 7, Gaussian
#: sigma 3, 15 x 15 kernels), taken as lengths at the thesis's 4.9 um pixel
_WEIGHTS_AT = {"dilate_radius": 7, "smooth_sigma": 3.0}
#: integrator label -> function(normals, object_mask) -> heights (pixel units)
INTEGRATORS = {
    "poisson": lambda n, m: integrate(n, object_mask=m, integrator="poisson"),
    "bilateral": lambda n, m: bilateral_integrate(n, object_mask=m),
}
_WARM = set()


def warm_up_integrators(names):
    """Integrate a small disc once per process with each integrator in ``names``, untimed,
    so that a stage's ``integrate_s`` is the integration's own time: the first masked
    Poisson solve of a process loads its compiled kernels (about 0.2 s against 0.01 s for
    a 200 x 200 disc), a cost that would land on whichever case comes first. The disc
    (about 3,200 pixels) is larger than :data:`~psbench.integrate.poisson.SMALL_COMPONENT`
    so that it takes the conjugate-gradient path."""
    for name in names:
        if name in _WARM:
            continue
        yy, xx = np.mgrid[-1:1:64j, -1:1:64j]
        n = np.dstack([0.1 * xx, 0.05 * yy, np.ones_like(xx)]).astype(np.float32)
        n /= np.linalg.norm(n, axis=2, keepdims=True)
        INTEGRATORS[name](n, xx ** 2 + yy ** 2 < 0.95)
        _WARM.add(name)


#: the method label of the ground-truth heights (upper bound of the identification)
TRUTH = "ground truth"
#: the method label of the ground-truth normals, integrated (what a perfect PS gives)
TRUTH_NORMALS = "ground-truth normals"


def recipes() -> dict:
    """Every registered recipe, label -> keyword arguments of :func:`psbench.solve`
    (psbench's :data:`RECIPES` first, then plug-ins')."""
    return {name: dict(r.solve) for name, r in registry.recipes().items()}


def solve_kwargs(label, pixel_size):
    """Keyword arguments of :func:`psbench.solve` for a registered method label
    (:func:`recipes`).

    ``weights_um``: the weighted masks' dilation radius and blur sigma are physical
    lengths, the thesis's pixel values at its 4.9 um pixel (34 um and 15 um), converted
    to this pixel size (radius rounded, at least 1; kernel 2 x radius + 1). At 4.9 um
    it is the thesis's setting; on coarser images the thesis's pixel values blur over
    larger areas of the case (at 9.8 um the default dilation reaches 69 um).
    """
    known = recipes()
    if label not in known:
        raise PsbenchError(f"method {label!r} is not known; valid choices: {', '.join(known)}")
    kw = known[label]
    if kw.pop("weights_um", False):
        f = DEFAULT_PIXEL_SIZE / float(pixel_size)
        r = max(1, int(round(_WEIGHTS_AT["dilate_radius"] * f)))
        kw.update(dilate_radius=r, kernel_size=2 * r + 1,
                  smooth_sigma=_WEIGHTS_AT["smooth_sigma"] * f)
    return kw


def roughness(normals, object_mask):
    """Mean angle (deg) between 4-neighbour normals inside ``object_mask``: noise and
    false edges raise it above the true surface's."""
    n = np.asarray(normals, np.float32)
    m = np.asarray(object_mask, bool)
    out = []
    for a, b, ma in ((n[:, 1:], n[:, :-1], m[:, 1:] & m[:, :-1]),
                     (n[1:], n[:-1], m[1:] & m[:-1])):
        c = np.einsum("...c,...c->...", a, b)[ma]
        out.append(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))
    v = np.concatenate(out)
    return float(v.mean()) if v.size else float("nan")


def _detrend(d, region, plane):
    if not plane:
        return d[region] - np.median(d[region])
    levelled, _ = level(d, region, trim=1e9, rounds=0)
    return levelled[region]


def height_error(height, truth, region, *, plane=False):
    """Mean absolute height error over ``region`` after removing the best offset
    (median) or, with ``plane``, the least-squares plane of the difference.

    Heights in any common unit (µm here); returns NaN for an empty region."""
    region = np.asarray(region, bool)
    if region.sum() < 3:
        return float("nan")
    d = np.asarray(height, np.float64) - np.asarray(truth, np.float64)
    return float(np.abs(_detrend(d, region, plane)).mean())


@dataclass(eq=False)
class Reconstruction:
    """Everything :func:`reconstruct` produced for one case.

    Attributes
    ----------
    rows : list of dict
        One row per (method, integrator): ``gun, case, method, integrator, ne,
        ne_breech_face, ne_firing_pin, roughness, err_firing_pin_um, err_wall_um,
        err_breech_face_um, acquire_s, solve_s, integrate_s``.
    filtered : dict
        (method, integrator, region) -> (band-passed heights (µm), valid mask), cropped
        to the region's bounding box; the ground truth under (:data:`TRUTH`, "-", region).
    normals : dict
        method -> (H, W, 3) normals (only with ``keep_normals``).
    acquisition : Acquisition or None
        Only with ``keep_normals``.
    pose : dict
        The case's :attr:`Cartridge.pose` (ground truth of the registration).
    """

    rows: list
    filtered: dict
    normals: dict
    acquisition: object = None
    pose: dict = None


def _crop(z, m):
    rr, cc = np.nonzero(m)
    sl = (slice(rr.min(), rr.max() + 1), slice(cc.min(), cc.max() + 1))
    return np.ascontiguousarray(z[sl]), np.ascontiguousarray(m[sl])


def reconstruct(cartridge, *, methods=tuple(RECIPES), integrators=tuple(INTEGRATORS),
                seed=0, short=None, long=LONG_CUTOFF, keep_normals=False,
                solve_options=None, truth_normals=False, compare=("breech_face",),
                domain="case"):
    """Acquire, solve, integrate and filter one case with every method and integrator.

    Parameters
    ----------
    cartridge : Cartridge
    methods : sequence of str
        Labels of :func:`recipes` (default: psbench's :data:`RECIPES`).
    integrators : sequence of str
        Keys of :data:`INTEGRATORS`.
    seed : int
        Camera-noise seed of the acquisition.
    short, long : float
        Band-pass cut-offs (µm) for the comparison (see :func:`~.identify.bandpass`).
    keep_normals : bool
        Keep the normals and the acquisition (for figures).
    solve_options : dict, optional
        Extra keyword arguments for every :func:`psbench.solve` call.
    truth_normals : bool
        Also integrate the ground-truth normals (method :data:`TRUTH_NORMALS`): the
        integrators' own share of the error, and the identification's upper bound
        through integration.
    compare : sequence of str
        Regions (keys of :attr:`Cartridge.regions`) whose band-passed heights are kept
        for the identification: ``"breech_face"`` (the field's comparison) and/or
        ``"firing_pin"`` (the impression, where shadows and highlights are).
    domain : {"case", "primer"}
        Where the normals are integrated: the whole case head, or only the primer
        (which holds both comparison regions; forensic systems crop it before the
        comparison, and integration costs less).

    Returns
    -------
    Reconstruction
    """
    kwargs = {name: solve_kwargs(name, cartridge.pixel_size) for name in methods}
    for name in integrators:
        if name not in INTEGRATORS:
            raise PsbenchError(f"integrator {name!r} is not known; valid choices: "
                               f"{', '.join(INTEGRATORS)}")
    c = cartridge
    ps_ = c.pixel_size
    reg = c.regions
    bf = reg["breech_face"] & c.object_mask
    truth = c.height_um
    for region in compare:
        if region not in reg:
            raise PsbenchError(f"compare region {region!r} is not known; valid choices: "
                               f"{', '.join(reg)}")
    rois = {r: reg[r] & c.object_mask for r in compare}
    if domain not in ("case", "primer"):
        raise PsbenchError(f"domain={domain!r} is not known; valid choices: case, primer")
    area = c.object_mask & (reg["primer"] if domain == "primer" else True)

    def keep(label, integ, h):
        for r, roi in rois.items():
            filtered[(label, integ, r)] = _crop(
                bandpass(h, roi, pixel_size=ps_, short=short, long=long), roi)

    warm_up_integrators(integrators)
    t0 = time.perf_counter()
    acq = acquire(c, seed=seed) if methods else None
    t_acq = time.perf_counter() - t0
    filtered = {}
    keep(TRUTH, "-", truth)
    rows, normals = [], {}
    for name in ((TRUTH_NORMALS,) if truth_normals else ()) + tuple(methods):
        t0 = time.perf_counter()
        if name == TRUTH_NORMALS:
            res, n = None, c.normals
        else:
            res = solve(acq.images, acq.lights, object_mask=c.object_mask, **kwargs[name],
                        **(solve_options or {}))
            n = res.normals
        t_solve = time.perf_counter() - t0
        if keep_normals:
            normals[name] = n
        base = {"gun": c.gun, "case": c.case, "method": name,
                "ne": normal_error(n, c.normals, object_mask=c.object_mask),
                "ne_breech_face": normal_error(n, c.normals, object_mask=bf),
                "ne_firing_pin": normal_error(n, c.normals, object_mask=reg["firing_pin"]),
                "roughness": roughness(n, c.object_mask),
                "acquire_s": t_acq if res is not None else 0.0, "solve_s": t_solve}
        for integ in integrators:
            t0 = time.perf_counter()
            h = INTEGRATORS[integ](n, area) * np.float32(ps_)
            t_int = time.perf_counter() - t0
            rows.append({**base, "integrator": integ, "integrate_s": t_int,
                         "err_firing_pin_um": height_error(h, truth, reg["firing_pin"]),
                         "err_wall_um": height_error(h, truth, reg["firing_pin_wall"]),
                         "err_breech_face_um": height_error(h, truth, bf, plane=True)})
            keep(name, integ, h)
        del res, n
    return Reconstruction(rows, filtered, normals, acq if keep_normals else None, dict(c.pose))


def score_pairs(filtered, *, sister=None, poses=None, **register_options):
    """CCFmax of every pair of cases.

    Parameters
    ----------
    filtered : dict
        (gun, case) -> (band-passed heights, valid mask), e.g. one entry of
        :attr:`Reconstruction.filtered` per case.
    sister : callable, optional
        ``sister(key_a, key_b) -> bool``; default: same gun (``key[0]``).
    poses : dict, optional
        key -> :attr:`Cartridge.pose`: adds ``angle_true`` (the rotation that lays b's
        gun marks on a's) and ``angle_error`` (degrees, sister pairs only).
    **register_options
        Passed to :func:`~.identify.register`.

    Returns
    -------
    DataFrame
        ``a, b`` (keys), ``sister``, ``ccf``, ``angle``, ``overlap``, ``seconds``.
    """
    same = sister or (lambda a, b: a[0] == b[0])
    rows = []
    for ka, kb in itertools.combinations(sorted(filtered), 2):
        (za, ma), (zb, mb) = filtered[ka], filtered[kb]
        t0 = time.perf_counter()
        m = register(za, zb, ma, mb, **register_options)
        row = {"a": ka, "b": kb, "sister": bool(same(ka, kb)), "ccf": m.ccf,
               "angle": m.angle, "overlap": m.overlap, "seconds": time.perf_counter() - t0}
        if poses is not None:
            true = (poses[ka]["gun_angle"] - poses[kb]["gun_angle"]) % 360.0
            err = abs((m.angle - true + 180.0) % 360.0 - 180.0)
            row.update(angle_true=true, angle_error=err if row["sister"] else float("nan"))
        rows.append(row)
    return pd.DataFrame(rows)


def auc(positive, negative):
    """Area under the ROC curve: P(score of a positive > score of a negative), ties 1/2."""
    p = np.asarray(positive, float)
    q = np.asarray(negative, float)
    p, q = p[np.isfinite(p)], q[np.isfinite(q)]
    if not len(p) or not len(q):
        return float("nan")
    gt = (p[:, None] > q[None, :]).sum()
    eq = (p[:, None] == q[None, :]).sum()
    return float((gt + 0.5 * eq) / (len(p) * len(q)))


def separation(scores, by=("region", "method", "integrator")):
    """Per group: sister / non-sister score statistics, separation and AUC.

    ``separation`` = smallest sister CCFmax - largest non-sister CCFmax (> 0: a
    threshold separates every pair); ``auc`` as :func:`auc`; ``registered`` the
    fraction of sister pairs registered within 1° of the true rotation (when the
    scores carry ``angle_error``).
    """
    out = []
    for key, g in scores.groupby(list(by), sort=False):
        s, n = g.loc[g.sister, "ccf"], g.loc[~g.sister, "ccf"]
        out.append({**dict(zip(by, key if isinstance(key, tuple) else (key,))),
                    "sister_min": s.min(), "sister_median": s.median(),
                    "non_sister_median": n.median(), "non_sister_max": n.max(),
                    "separation": s.min() - n.max(), "auc": auc(s, n),
                    "n_sister": int(len(s)), "n_non_sister": int(len(n)),
                    "registered": (float((g.loc[g.sister, "angle_error"] < 1.0).mean())
                                   if "angle_error" in g else float("nan"))})
    return pd.DataFrame(out)


def evaluate(guns, cases, *, size=512, methods=tuple(RECIPES),
             integrators=tuple(INTEGRATORS), seed=0, short=None, long=LONG_CUTOFF,
             solve_options=None, register_options=None, truth_normals=True,
             compare=("breech_face", "firing_pin"), domain="case", progress=None):
    """The Chapter 7 table: reconstruct every case, score every pair per method.

    Parameters
    ----------
    guns, cases : sequence of int
        Every gun fires every case seed: ``len(guns) * len(cases)`` cases, sisters
        share the gun.
    size : int, default 512
        Image side (pixel size 4.9 x 2048 / size µm).
    methods, integrators, seed, short, long, solve_options, truth_normals, compare, domain
        As :func:`reconstruct`.
    register_options : dict, optional
        Passed to :func:`~.identify.register`.
    progress : callable, optional
        Called with a short message after each case and each scored group.

    Returns
    -------
    per_case : DataFrame
        :attr:`Reconstruction.rows` of every case.
    scores : DataFrame
        :func:`score_pairs` rows with ``region``, ``method`` and ``integrator`` columns.
    summary : DataFrame
        :func:`separation` per (region, method, integrator), ground truth included,
        joined with the mean NE, height errors and times of each method/integrator.
    """
    per_case, by_group, poses = [], {}, {}
    for g, cs in itertools.product(guns, cases):
        rec = reconstruct(make_cartridge(size, gun=g, case=cs), methods=methods,
                          integrators=integrators, seed=seed, short=short, long=long,
                          solve_options=solve_options, truth_normals=truth_normals,
                          compare=compare, domain=domain)
        per_case.extend(rec.rows)
        poses[(g, cs)] = rec.pose
        for key, val in rec.filtered.items():
            by_group.setdefault(key, {})[(g, cs)] = val
        if progress:
            progress(f"case gun={g} case={cs} done")
    frames = []
    for (method, integ, region), filt in by_group.items():
        sc = score_pairs(filt, poses=poses, **(register_options or {}))
        sc.insert(0, "integrator", integ)
        sc.insert(0, "method", method)
        sc.insert(0, "region", region)
        frames.append(sc)
        if progress:
            progress(f"scored {region}: {method} / {integ}")
    scores = pd.concat(frames, ignore_index=True)
    per_case = pd.DataFrame(per_case)
    summary = separation(scores)
    if len(per_case):
        means = per_case.groupby(["method", "integrator"], sort=False)[
            ["ne", "ne_breech_face", "ne_firing_pin", "roughness", "err_firing_pin_um",
             "err_wall_um", "err_breech_face_um", "solve_s", "integrate_s"]].mean().reset_index()
        summary = summary.merge(means, on=["method", "integrator"], how="left")
    return per_case, scores, summary


def _capture(surface, method, integrator, reference, seed, short, long):
    """Acquire, solve, integrate one orientation; metrics against its own ground truth."""
    reg, ps_ = surface.regions, surface.pixel_size
    bf = reg["breech_face"] & surface.object_mask
    acq = acquire(surface, seed=seed)
    res = solve(acq.images, acq.lights, object_mask=surface.object_mask,
                **solve_kwargs(method, ps_))
    h = INTEGRATORS[integrator](res.normals, surface.object_mask) * np.float32(ps_)
    _, fitted = level(h, surface.object_mask, pixel_size=ps_)
    fp, case = reg["firing_pin"], surface.object_mask
    fb = bandpass(h, bf, pixel_size=ps_, short=short, long=long)
    match = register(reference[0], fb, reference[1], bf)
    return {"ne": normal_error(res.normals, surface.normals, object_mask=case),
            "ne_firing_pin": normal_error(res.normals, surface.normals, object_mask=fp),
            "highlight": float(acq.highlight[:, case].mean()),
            "shadow": float(acq.shadow[:, case].mean()),
            "shadow_firing_pin": float(acq.shadow[:, fp].mean()),
            "saturated": acq.saturated,
            "levelled_tilt": fitted.tilt,
            "err_firing_pin_um": height_error(h, surface.height_um, fp),
            "err_wall_um": height_error(h, surface.height_um, reg["firing_pin_wall"]),
            "err_breech_face_um": height_error(h, surface.height_um, bf, plane=True),
            "ccf_truth": match.ccf}


def plane_study(cartridge, tilts=(1.0, 3.0, 5.0), *, azimuth=30.0,
                method="weighted Th-Hi-Re-Sh", first_pass="Th", integrator="poisson",
                tol=0.05, max_rounds=5, seed=0, short=None, long=LONG_CUTOFF):
    """What the sample-plane correction buys (Section 1.4), as a tidy table.

    For every tilt (and 0, the level reference) the case is mounted tilted towards
    ``azimuth`` and captured twice: as mounted, with the computational correction only
    (heights levelled by :func:`~.plane.level`), and after the closed-loop stage
    correction (:func:`~.plane.level_sample` with a ``first_pass`` solve and
    :func:`~.plane.estimate_plane`). Each capture is solved with ``method``, integrated
    with ``integrator`` and measured against its own ground truth; ``ccf_truth`` is the
    CCFmax of its band-passed breech face against the level case's true one.

    Returns
    -------
    DataFrame
        One row per (tilt, correction): ``tilt, correction ("computational" or
        "stage"), estimated_tilt`` (first pass on the mounted sample, or the tilt the
        loop recovered), ``tilt_error`` (degrees between true and estimated normals),
        ``residual_tilt`` (after the stage loop), ``rounds``, then the capture metrics
        of :func:`_capture`.
    """
    c = cartridge
    bf = c.regions["breech_face"] & c.object_mask
    reference = (bandpass(c.height_um, bf, pixel_size=c.pixel_size, short=short, long=long), bf)

    def first(surface):
        acq = acquire(surface, seed=seed)
        res = solve(acq.images, acq.lights, object_mask=surface.object_mask,
                    **recipes().get(first_pass, {"mask": first_pass}))
        return estimate_plane(res.normals, surface.object_mask)

    rows = []
    for tilt in (0.0,) + tuple(float(t) for t in tilts if t):
        mounted = tilt_surface(c, tilt, azimuth) if tilt else c
        truth = Plane.from_angles(tilt, azimuth)

        def off(p):
            return float(np.degrees(np.arccos(np.clip(p.normal @ truth.normal, -1, 1))))

        est = first(mounted)
        rows.append({"tilt": tilt, "correction": "computational", "estimated_tilt": est.tilt,
                     "tilt_error": off(est), "residual_tilt": tilt, "rounds": 1,
                     **_capture(mounted, method, integrator, reference, seed, short, long)})
        levelled, recovered, hist = level_sample(mounted, first, tol=tol, max_rounds=max_rounds)
        rows.append({"tilt": tilt, "correction": "stage", "estimated_tilt": recovered.tilt,
                     "tilt_error": off(recovered),
                     "residual_tilt": float(levelled.pose.get("tilt", 0.0)),
                     "rounds": len(hist),
                     **_capture(levelled, method, integrator, reference, seed, short, long)})
    return pd.DataFrame(rows)


__getattr__ = renamed_names(globals(), {"METHODS": "RECIPES"})
