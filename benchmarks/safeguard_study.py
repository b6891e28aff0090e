"""Can held-out prediction decide, per pixel, between tsfit and the trimmed fit?

For each scene (Torrance-Sparrow renders at 128^2, 30x8+60x8, with and without one
interreflection bounce, and DiLiGenT cat and bear with 96 lights) this script runs
``trim`` and the Torrance-Sparrow step of ``robust`` (``tsfit`` with
``robust.TS_SETTINGS``), computes the held-out errors of both fits
(:mod:`psbench.solve.validation`) and evaluates candidate fallback rules: keep the
Torrance-Sparrow normal at a pixel iff its truncated held-out loss (squared errors in
units of a model-free noise scale per image, truncated at 3, averaged over a
(2r+1)^2 window of object pixels) is at most that of the trimmed fit plus a margin d,
on one of the evaluation sets

* ``onC``: the observations tsfit used (trim predicts those it did not fit);
* ``onS``: the observations trim kept;
* ``union``: either.

The noise scale of image i is 1.4826 median |I * N| / 6 over the lit interior pixels
(N the 3x3 second-difference kernel of Immerkaer, CVIU 1996), floored at 1e-3 of the
median lit intensity. Prints, per rule, the mean NE per scene (and the fraction of
pixels that fell back).

Usage::

    python benchmarks/safeguard_study.py [--data DIR] [--cache /tmp/safeguard]
"""
from __future__ import annotations

import argparse
import glob
import os
from pathlib import Path

import numpy as np

SCENES = [(s, b, "30x8+60x8", n) for s in ("semisphere", "spheres", "sombrero", "mozart", "penny",
                                           "cup", "vgroove") for b in (0, 1) for n in (0.02,)]
SCENES += [(s, b, "30x8+60x8", n) for s in ("cup", "sombrero") for b in (0, 1) for n in (0.0, 0.05)]
LAPLACE = np.array([[1, -2, 1], [-2, 4, -2], [1, -2, 1]], float)


def ang(a, b):
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1, 1)))


def gather(path, images, lay, om, gt):
    import psbench as ps
    from scipy.ndimage import binary_erosion, convolve
    from psbench.solve.methods.tsfit import _lm
    from psbench.solve.methods.robust import TS_SETTINGS
    from psbench.solve.validation import lambert_heldout, ts_heldout
    k = lay.k
    I = images.reshape(k, -1)[:, om.reshape(-1)].astype(np.float32)
    tr = ps.solve(images, lay, method="trim", object_mask=om)
    ts = ps.solve(images, lay, method="tsfit", object_mask=om, **TS_SETTINGS)
    wS = tr.valid.reshape(k, -1)[:, om.reshape(-1)].astype(np.float32)
    wC = ts.weights.reshape(k, -1)[:, om.reshape(-1)].astype(np.float32)
    L = _lm.Lights(lay.directions, lay.power)
    n = ts.normals[om].T
    eS = lambert_heldout(I, lay.S, wS)
    eC = ts_heldout(I, L.table, wC, n, ts.albedo[om], ts.info["rho_s"], ts.info["m"])
    inner = binary_erosion(om, iterations=2)
    sig = []
    for img in images:
        r = convolve(img.astype(float), LAPLACE)[inner]
        sig.append(1.4826 * np.median(np.abs(r[img[inner] > 0])) / 6)
    np.savez(path, eS=eS, eC=eC, wS=wS, wC=wC, sig=np.array(sig), om=om, I=I,
             ne_t=ang(tr.normals[om], gt[om]), ne_c=ang(ts.normals[om], gt[om]))


def pool(v, om, r):
    from scipy.ndimage import uniform_filter
    if r == 0:
        return v
    A = np.zeros(om.shape)
    A[om] = v
    return uniform_filter(A, 2 * r + 1, mode="constant")[om]


def losses(d, r, c=3.0):
    I = d["I"]
    sig = np.maximum(d["sig"], 1e-3 * np.median(I[I > 0]))[:, None]
    om = d["om"]
    l = {m: np.minimum(np.nan_to_num(d[e] / sig, nan=1e3) ** 2, c * c) for m, e in (("C", "eC"), ("S", "eS"))}
    sets = {"onC": d["wC"] > 0, "onS": d["wS"] > 0, "union": (d["wC"] > 0) | (d["wS"] > 0)}
    out = {}
    for name, E in sets.items():
        cnt = np.maximum(pool(E.sum(0).astype(float), om, r), 1e-9)
        out[name] = tuple(pool((l[m] * E).sum(0), om, r) / cnt for m in ("C", "S"))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / "../shared/data/diligent"))
    ap.add_argument("--cache", default="/tmp/safeguard")
    a = ap.parse_args(argv)
    import psbench as ps
    os.makedirs(a.cache, exist_ok=True)
    for obj in ("cat", "bear"):
        p = f"{a.cache}/{obj}.npz"
        if not os.path.exists(p):
            d = ps.io.read_dataset(f"{a.data}/{obj}")
            gather(p, d.images, ps.layout(d.lights), d.object_mask, d.normals)
    for s, b, lights, noise in SCENES:
        p = f"{a.cache}/{s}_b{b}_n{noise}.npz"
        if not os.path.exists(p):
            surf, lay = ps.make_surface(s, size=128), ps.layout(lights)
            sc = ps.render(surf, lay, model="ts", noise=noise, seed=0, bounces=b)
            gather(p, sc.images, lay, surf.object_mask, surf.normals)
    D = {Path(f).stem: dict(np.load(f)) for f in sorted(glob.glob(f"{a.cache}/*.npz"))}
    print("scene: NE trim / tsfit step / per-pixel oracle")
    for t, d in D.items():
        print(f"  {t:24s} {d['ne_t'].mean():6.2f} {d['ne_c'].mean():6.2f} "
              f"{np.minimum(d['ne_t'], d['ne_c']).mean():6.2f}")
    for r in (0, 2):
        L = {t: losses(d, r) for t, d in D.items()}
        for rule in ("onC", "onS", "union"):
            for dl in (-0.25, 0.0, 0.25, 0.5):
                cells, diff = [], []
                for t, d in D.items():
                    qC, qS = L[t][rule]
                    keep = qC <= qS + dl
                    ne = np.where(keep, d["ne_c"], d["ne_t"]).mean()
                    diff.append(ne - d["ne_c"].mean())
                    cells.append(f"{t} {ne:.2f} ({100 * (1 - keep.mean()):.0f}%)")
                print(f"r={r} {rule:5s} d={dl:+.2f} mean NE change vs tsfit step {np.mean(diff):+.2f}: "
                      + "; ".join(cells))


if __name__ == "__main__":
    main()
