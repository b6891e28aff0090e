"""The Chapter 7 study as runs of the benchmark harness (experiment ``chapter7``).

``psbench +experiment=chapter7`` runs :func:`run` through
:func:`psbench.analysis.forensic` (``kind=analysis``) and stores its json payload, one
row per run. The study draws ``guns`` x ``cases`` cartridge cases (guns ``first_gun``,
``first_gun + 1``, ...; case seeds 1..``cases``; sisters share the gun) at the run's
``size``, acquires each with the Chapter 7 rig (:func:`~.presets.acquire`, camera noise
seed = the run's ``seed``) and evaluates them with :mod:`psbench.forensic.pipeline`.
A run is one ``part``:

``method``
    One method label of :func:`~.pipeline.recipes` on every case: per case and
    integrator NE, roughness, height errors (µm) and the stage times (acquire, solve,
    integrate); the CCFmax of every pair of cases per (integrator, region), with the
    registration's angle error and time. When the study's ``time_size`` differs from
    the run's size, also the whole pipeline for this method on the sister pair of the
    thesis (gun 3: case 5 against case 3's true, band-passed breech face, a database
    entry) at ``time_size``: acquire, solve, integrate (every integrator, over the
    primer), compare; wall and CPU seconds.
``truth``
    The references on every case: the ground-truth heights (:data:`~.pipeline.TRUTH`,
    the identification's upper bound) and the integrated ground-truth normals
    (:data:`~.pipeline.TRUTH_NORMALS`).
``panels``
    The Figs. 7.3-7.9 analogues for that pair (:mod:`._panels`) and the numbers of the
    Chapter 7 claims (highlights and shadows per ring and region, masked fractions, WPS
    ring weights on the firing-pin walls).

Heights are integrated over the primer (``domain="primer"`` of
:func:`~.pipeline.reconstruct`), which holds both comparison regions. ``study`` (a run
parameter, set by the experiment's scale) overrides :data:`STUDY`.
"""
from __future__ import annotations

import time

import numpy as np
import pandas as pd

from .._shared.checks import PsbenchError
from . import _panels as V
from . import pipeline as P
from .cartridge import check_seed, make_cartridge
from .identify import bandpass, register
from .presets import acquire

__all__ = ["STUDY", "PARTS", "PAIR", "PANEL_METHODS", "run", "case_keys"]

#: defaults of the ``study`` run parameter
STUDY = {"guns": 6, "cases": 3, "first_gun": 1, "time_size": None,
         "integrators": list(P.INTEGRATORS), "regions": ["breech_face", "firing_pin"]}
PARTS = ("method", "truth", "panels")
#: the thesis's sister pair (gun, case a, case b): cartridge cases 3 and 5
PAIR = (3, 3, 5)
#: methods of the normals and render panels (the thesis's Figs. 7.8-7.9)
PANEL_METHODS = ("None", "Th-Hi-Re-Sh", "weighted Th-Hi-Re-Sh", "WPS")
_PANEL_SIDE = 480          # longest side of a close-up panel (pixels)
_TILE = 160                # side of one image of a 16-image montage


def _options(study):
    st = dict(STUDY)
    st.update(study or {})
    bad = sorted(set(st) - set(STUDY))
    if bad:
        raise PsbenchError(f"study has unknown key(s) {bad}; valid: {', '.join(STUDY)}")
    for k in ("guns", "cases"):
        if isinstance(st[k], bool) or not isinstance(st[k], (int, np.integer)) or st[k] < 2:
            raise PsbenchError(f"study {k} must be an integer >= 2, got {st[k]!r}")
    st["first_gun"] = check_seed(st["first_gun"], "study first_gun")
    if st["time_size"] is not None and (isinstance(st["time_size"], bool) or
                                        not isinstance(st["time_size"], (int, np.integer))):
        raise PsbenchError(f"study time_size must be an integer or null, got {st['time_size']!r}")
    for k, valid in (("integrators", P.INTEGRATORS), ("regions", ("breech_face", "firing_pin"))):
        st[k] = [st[k]] if isinstance(st[k], str) else list(st[k])
        if not st[k] or any(v not in valid for v in st[k]):
            raise PsbenchError(f"study {k}={st[k]!r}: valid entries are {', '.join(valid)}")
    return st


def case_keys(study=None):
    """``[(gun, case), ...]`` of a study (every gun fires case seeds 1..cases)."""
    st = _options(study)
    return [(g, c) for g in range(st["first_gun"], st["first_gun"] + st["guns"])
            for c in range(1, st["cases"] + 1)]


def run(part="method", label=None, *, size=1024, seed=0, study=None):
    """One run of the Chapter 7 study (see the module docstring).

    Parameters
    ----------
    part : {"method", "truth", "panels"}
    label : str
        Method label (:func:`~.pipeline.recipes`) of a ``method`` run.
    size : int
        Image side of the study (pixel size 4.9 x 2048 / size µm).
    seed : int
        Camera-noise seed of every acquisition.
    study : dict, optional
        Overrides of :data:`STUDY`.

    Returns
    -------
    dict
        json-able payload; tables are lists of records.
    """
    if part not in PARTS:
        raise PsbenchError(f"part={part!r} is not known; valid choices: {', '.join(PARTS)}")
    st = _options(study)
    if part == "method":
        if label is None:
            raise PsbenchError(f"part={part!r} needs label=<one of {', '.join(P.recipes())}>")
        P.solve_kwargs(label, 4.9)                 # unknown labels fail before any work
    make_cartridge(size, gun=PAIR[0], case=PAIR[1])    # size too small: fails here
    head = {"part": part, "label": label, "size": int(size), "seed": int(seed)}
    if part == "panels":
        return {**head, **_panel_payload(size, seed)}
    out = {**head, **_cases(part, label, size, seed, st)}
    if part == "method" and st["time_size"] and st["time_size"] != size:
        out["timing"] = _timing(label, st["time_size"], seed, st["integrators"])
    return out


def _cases(part, label, size, seed, st):
    keys = case_keys(st)
    per_case, filtered, poses = [], {}, {}
    for g, c in keys:
        cart = make_cartridge(size, gun=g, case=c)
        rec = P.reconstruct(cart, methods=(label,) if part == "method" else (),
                            integrators=st["integrators"], seed=seed,
                            truth_normals=part == "truth", compare=st["regions"],
                            domain="primer")
        per_case.extend(rec.rows)
        poses[(g, c)] = rec.pose
        for (lab, integ, region), val in rec.filtered.items():
            if part == "truth" or lab == label:
                filtered.setdefault((lab, integ, region), {})[(g, c)] = val
        del rec, cart
    frames = []
    for (lab, integ, region), filt in filtered.items():
        sc = P.score_pairs(filt, poses=poses)
        sc.insert(0, "integrator", integ)
        sc.insert(0, "method", lab)
        sc.insert(0, "region", region)
        frames.append(sc)
    scores = pd.concat(frames, ignore_index=True)
    scores["a"] = scores["a"].map(list)
    scores["b"] = scores["b"].map(list)
    ps_ = make_cartridge(size, gun=PAIR[0], case=PAIR[1]).pixel_size
    return {"pixel_size": ps_, "cases": [list(k) for k in keys],
            "per_case": pd.DataFrame(per_case).to_dict(orient="records"),
            "scores": scores.to_dict(orient="records")}


def _stopwatch():
    last = [time.perf_counter(), time.process_time()]
    out = {}

    def lap(name):
        w, c = time.perf_counter(), time.process_time()
        out[name] = {"wall": w - last[0], "cpu": c - last[1]}
        last[:] = [time.perf_counter(), time.process_time()]

    return out, lap


def _timing(label, size, seed, integrators):
    """The benchmark's pipeline (benchmarks/forensic_pipeline.py) inside a run."""
    from ..solve import solve

    gun, ca, cb = PAIR
    ref = make_cartridge(size, gun=gun, case=ca)
    bf_ref = ref.regions["breech_face"]
    ref_f = bandpass(ref.height_um, bf_ref, pixel_size=ref.pixel_size)
    case = make_cartridge(size, gun=gun, case=cb)
    bf = case.regions["breech_face"]
    stages, lap = _stopwatch()
    acq = acquire(case, seed=seed)
    lap("acquire")
    res = solve(acq.images, acq.lights, object_mask=case.object_mask,
                **P.solve_kwargs(label, case.pixel_size))
    normals = res.normals
    del acq, res
    lap("solve")
    heights, area = {}, case.object_mask & case.regions["primer"]
    for integ in integrators:
        heights[integ] = P.INTEGRATORS[integ](normals, area) * np.float32(case.pixel_size)
        lap(f"integrate_{integ}")
    first = integrators[0]
    m = register(ref_f, bandpass(heights[first], bf, pixel_size=case.pixel_size), bf_ref, bf)
    lap("compare")
    total = {k: sum(stages[s][k] for s in ("acquire", "solve", f"integrate_{first}", "compare"))
             for k in ("wall", "cpu")}
    return {"time_size": int(size), "pixel_size": case.pixel_size, "stages": stages,
            "pipeline": total, "pipeline_integrator": first, "ccf": m.ccf,
            "ne": P.normal_error(normals, case.normals, object_mask=case.object_mask)}


def _residual(acq, res):
    """Signed Lambert residuals I - rho s.n of a solve, (k, H, W) float32."""
    from ..solve import kernel

    images = acq.images.astype(np.float32) / np.float32(2 ** acq.bits - 1)
    b = res.normals * res.albedo[..., None]
    return images - kernel.lambert(b.astype(np.float32), acq.lights.S)


def _panel_payload(size, seed):
    """Panels and claim numbers for the sister pair :data:`PAIR`."""
    from ..solve import solve

    gun, ca, cb = PAIR
    cases = {c: make_cartridge(size, gun=gun, case=c) for c in (ca, cb)}
    a = cases[ca]
    ps_ = a.pixel_size
    acqs = {c: acquire(cases[c], seed=seed) for c in (ca, cb)}
    acq = acqs[ca]
    m = a.object_mask
    rings = acq.lights.rings()
    images, claims = {}, {}
    # Figs. 7.3 / 7.4: raw 8-bit and calibrated (float, max 1; clipped pixels red)
    raw = [V.thumb(img, _TILE) for img in acq.images]
    images["raw"] = V.encode(V.montage(raw, 2), "jpg")
    full = float(2 ** acq.bits - 1)
    calib = []
    for img in acq.images:
        f = img.astype(np.float32) / np.float32(full)
        rgb = np.repeat(V.to_u8(f / max(float(acq.images.max()) / full, 1e-6))[..., None], 3, -1)
        rgb[img >= full] = (230, 30, 30)
        calib.append(V.thumb(rgb, _TILE))
    images["calibrated"] = V.encode(V.montage(calib, 2), "jpg")
    # solves of both cases with the panel methods (+ robust estimators for the claims)
    sols = {(lab, c): solve(acqs[c].images, acqs[c].lights, object_mask=cases[c].object_mask,
                            **P.solve_kwargs(lab, ps_))
            for lab in PANEL_METHODS for c in (ca, cb)}
    # Fig. 7.5: Th-Hi-Re-Sh masks of case a
    res = sols[("Th-Hi-Re-Sh", ca)]
    valid = np.asarray(res.valid, bool)
    resid = _residual(acq, res)
    ov = [V.thumb(V.mask_overlay(acq.images[i], ~valid[i], resid[i], m), _TILE)
          for i in range(len(acq.images))]
    images["masks"] = V.encode(V.montage(ov, 2), "png")
    # Fig. 7.6: WPS ring weights on the firing pin of case a
    fp = a.regions["firing_pin"]
    box = V.crop_box(fp, margin=0.25)
    w = sols[("WPS", ca)].ring_weights
    for j, z in enumerate(np.asarray(acq.lights.ring_zeniths)):
        images[f"weights_{int(round(z))}"] = V.encode(
            V.thumb(V.to_u8(np.where(m, w[j], 0)[box]), _PANEL_SIDE), "png")
    claims.update(_claims(a, acq, valid, w, rings))
    # Figs. 7.8 / 7.9: normals and shaded heights of both cases, b aligned to a's gun frame
    primer = V.crop_box(a.regions["primer"] & m, margin=0.02)
    bf_a = a.regions["breech_face"] & m
    rr, cc = np.nonzero(a.regions["firing_pin"])   # close-up: the firing pin and the
    half = int(0.5 * np.sqrt(a.regions["primer"].sum() / np.pi))   # breech face around it
    r0, c0 = int(rr.mean()), int(cc.mean())
    close = (slice(max(r0 - half, 0), r0 + half), slice(max(c0 - half, 0), c0 + half))
    for lab in ("ground truth",) + PANEL_METHODS:
        for c in (ca, cb):
            cart = cases[c]
            if lab == "ground truth":
                n, h = cart.normals, cart.height_um
            else:
                n = sols[(lab, c)].normals
                h = P.INTEGRATORS["poisson"](n, cart.object_mask) * np.float32(ps_)
            mm = cart.object_mask
            if c != ca:
                n = V.align(n, a.pose, cart.pose, ps_, vectors=True)
                h = V.align(h, a.pose, cart.pose, ps_)
                mm = V.align(mm.astype(np.uint8), a.pose, cart.pose, ps_, nearest=True) > 0
            nrgb = V.normals_rgb(n, mm)
            sh = V.shade(h, ps_, mm, stretch=bf_a & mm)
            images[f"normals/{lab}/{c}"] = V.encode(V.thumb(nrgb[primer], _PANEL_SIDE), "jpg")
            images[f"shade/{lab}/{c}"] = V.encode(V.thumb(sh[primer], _PANEL_SIDE), "jpg")
            if lab in ("ground truth", "weighted Th-Hi-Re-Sh"):
                whole = V.shade(h, ps_, mm)
                images[f"case/{lab}/{c}"] = V.encode(V.thumb(whole, _PANEL_SIDE), "jpg")
                images[f"close/{lab}/{c}"] = V.encode(V.thumb(sh[close], _PANEL_SIDE), "jpg")
    for lab in PANEL_METHODS:
        claims[f"roughness {lab}"] = P.roughness(sols[(lab, ca)].normals, m)
    claims["roughness ground truth"] = P.roughness(a.normals, m)
    return {"pixel_size": ps_, "pair": list(PAIR), "images": images, "claims": claims,
            "ring_zeniths": [float(z) for z in acq.lights.ring_zeniths]}


def _claims(a, acq, valid, ring_weights, rings):
    """Numbers behind the Chapter 7 claims on case a (percentages of observations)."""
    m = a.object_mask
    regs = {"case": m, "breech face": a.regions["breech_face"] & m,
            "firing pin": a.regions["firing_pin"] & m,
            "firing-pin wall": a.regions["firing_pin_wall"] & m}
    out = {}
    zen = np.asarray(acq.lights.ring_zeniths)
    for j, z in enumerate(zen):
        sel = rings[j]
        tag = f"{int(round(z))} deg"
        for rname, r in regs.items():
            if not r.any():
                continue
            out[f"highlight % {tag} {rname}"] = 100.0 * float(acq.highlight[sel][:, r].mean())
            out[f"shadow % {tag} {rname}"] = 100.0 * float(acq.shadow[sel][:, r].mean())
            out[f"masked % {tag} {rname}"] = 100.0 * float((~valid[sel][:, r]).mean())
            out[f"WPS weight {tag} {rname}"] = float(ring_weights[j][r].mean())
    # walls shadowed under the steeper-light ring: which ring weighs more there
    steep = int(np.argmax(zen))
    shadowed = acq.shadow[rings[steep]].any(axis=0) & regs["firing-pin wall"]
    if shadowed.any():
        for j, z in enumerate(zen):
            out[f"WPS weight {int(round(z))} deg shadowed wall"] = float(
                ring_weights[j][shadowed].mean())
    return out
