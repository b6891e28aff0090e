"""
A plug-in mask and method
=========================

psbench grows by registering pieces, not by editing lists. A mask is a
:class:`psbench.registry.Mask` (name, stage, function, thresholds); a method is a
:class:`psbench.registry.Method` (name, function, options dataclass). A package declares
them as entry points (see :doc:`/guide/plugins`); in a script or notebook
:func:`psbench.registry.register` adds them for the running process. Both then work in
mask expressions and ``method=`` like the built-ins.
"""
from dataclasses import dataclass

import matplotlib.pyplot as plt
import numpy as np

import psbench as ps
from psbench import registry
from psbench.registry import Mask, Method, Threshold
from psbench.solve.base import Fit, Options, check_number


def dark(images, ctx):
    """Valid where an observation is brighter than t_dark of the mean dynamic range."""
    return images >= np.float32(ctx.thresholds["t_dark"] * ctx.scale)


@dataclass
class ShrinkOptions(Options):
    """Options of ``shrink``.

    Parameters
    ----------
    factor : float
        Albedo factor in (0, 1]; default 0.5.
    """
    factor: float = 0.5

    def __post_init__(self):
        super().__post_init__()
        check_number(self.factor, "factor", lo=0, hi=1, lo_open=True)


def shrink(problem, options):
    """The masked least-squares solution with its albedo scaled by ``factor``."""
    return Fit(b=problem.start() * np.float32(options.factor))


registry.register("masks", Mask(
    "Dark", "image", dark, ranges=True,
    thresholds=(Threshold("t_dark", 0.05, (0.0, 1.0), help="fraction of the range"),),
    help="shadows: darker than t_dark of the mean dynamic range"), replace=True)
registry.register("methods", Method("shrink", shrink, options=ShrinkOptions,
                                    help="masked least squares, albedo times options.factor"),
                  replace=True)

# %%
# The new mask in an expression, with a threshold set per call, and the new method with
# its option
surf = ps.make_surface("sombrero2", size=128)
lay = ps.layout("45x8")
scene = ps.render(surf, lay, model="lambert", seed=0)
for mask in ["None", "Dark", "Th-Dark"]:
    res = ps.solve(scene.images, lay, mask=mask, object_mask=surf.object_mask,
                   thresholds={"t_dark": 0.02})
    ne = ps.normal_error(res.normals, surf.normals, object_mask=surf.object_mask)
    print(f"mask {mask:8s} NE {ne:5.2f} deg")
plain = ps.solve(scene.images, lay, mask="Dark", object_mask=surf.object_mask)
half = ps.solve(scene.images, lay, mask="Dark", method="shrink", factor=0.25,
                object_mask=surf.object_mask)
ratio = np.median(half.albedo[surf.object_mask] / plain.albedo[surf.object_mask])
print(f"shrink factor=0.25: albedo ratio {ratio:.2f}, same normals: "
      f"{np.allclose(half.normals, plain.normals, atol=1e-5)}")

# %%
# What ``Dark`` excluded (white) in each of the 8 images
res = ps.solve(scene.images, lay, mask="Dark", object_mask=surf.object_mask)
fig, axes = plt.subplots(1, 8, figsize=(12, 1.9), layout="constrained")
for i, ax in enumerate(axes):
    ax.imshow(~res.valid[i] & surf.object_mask, cmap="gray")
    ax.set_title(f"polar {lay.polar[i]:.0f}", fontsize=9)
    ax.axis("off")
