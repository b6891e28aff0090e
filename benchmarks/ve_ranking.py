"""How well does the validation error rank methods against the normal error?

Per scene, every method (and the thesis's mask Th-Hi-Re-Sh) is run with its defaults;
the mean validation error ``Result.ve.mean`` and the mean NE are compared by the
Spearman rank correlation over the methods (1: ve orders the methods exactly as NE
does). Scenes: Torrance-Sparrow renders (``--size``, 30x8+60x8, 2 % noise, with and
without one interreflection bounce) and DiLiGenT cat and bear (96 lights).

Usage::

    python benchmarks/ve_ranking.py [--size 64] [--data DIR] [--no-real]
"""
from __future__ import annotations

import argparse
import warnings
from pathlib import Path

import numpy as np

RUNS = [("ps", "None"), ("ps", "Th-Hi-Re-Sh"), ("trim", "None"), ("huber", "None"),
        ("cauchy", "None"), ("l1", "None"), ("robust", "None"), ("tsfit", "None")]


def spearman(a, b):
    from scipy.stats import spearmanr
    return float(spearmanr(a, b).statistic)


def scene_rows(images, lights, om, gt):
    import psbench as ps
    out = []
    for method, mask in RUNS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = ps.solve(images, lights, method=method, mask=mask, object_mask=om)
        out.append((f"{method}/{mask}", float(ps.normal_error(r.normals, gt, object_mask=om)),
                    r.ve.mean))
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--data", default=str(Path(__file__).resolve().parents[1] / "../shared/data/diligent"))
    ap.add_argument("--no-real", action="store_true")
    a = ap.parse_args(argv)
    import psbench as ps
    scenes = []
    lay = ps.layout("30x8+60x8")
    for s in ("sombrero", "mozart", "cup", "vgroove"):
        for b in (0, 1):
            surf = ps.make_surface(s, size=a.size)
            sc = ps.render(surf, lay, model="ts", noise=0.02, seed=0, bounces=b)
            scenes.append((f"{s} bounces={b}", sc.images, lay, surf.object_mask, surf.normals))
    if not a.no_real:
        for obj in ("cat", "bear"):
            d = ps.io.read_dataset(f"{a.data}/{obj}")
            scenes.append((obj, d.images, d.lights, d.object_mask, d.normals))
    rhos = []
    for name, images, lights, om, gt in scenes:
        rows = scene_rows(images, lights, om, gt)
        rho = spearman([r[1] for r in rows], [r[2] for r in rows])
        rhos.append(rho)
        best_ne = min(rows, key=lambda r: r[1])[0]
        best_ve = min(rows, key=lambda r: r[2])[0]
        print(f"\n{name}: Spearman(ve, NE) over {len(rows)} methods = {rho:+.2f}; lowest NE "
              f"{best_ne}, lowest ve {best_ve}")
        print("| method/mask | NE deg | ve mean |")
        print("|---|---|---|")
        for m, ne, ve in rows:
            print(f"| {m} | {ne:.2f} | {ve:.4f} |")
    print(f"\nmean Spearman over {len(rhos)} scenes: {np.mean(rhos):+.2f}")


if __name__ == "__main__":
    main()
