"""
A real DiLiGenT folder
======================

A folder in the DiLiGenT layout (numbered images, ``light_directions.txt``,
``light_intensities.txt``, ``mask.png``, ``Normal_gt.mat``) is read by
:func:`psbench.io.read_dataset` and solved like a rendered scene. Here DiLiGenT's ``cat``
(96 lights) from ``$PSBENCH_DATA/diligent/cat``, solved by least squares and with the
threshold mask ``Th`` (which drops each pixel's darkest and brightest observations:
shadows and highlights), against its ground-truth normals.
"""
import os
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import psbench as ps

folder = Path(os.environ.get("PSBENCH_DATA", "../shared/data")) / "diligent" / "cat"
ds = ps.io.read_dataset(folder)
print(f"{folder.name}: {ds.images.shape[0]} images of {ds.images.shape[1]} x {ds.images.shape[2]}")

fits = {}
for mask in [None, "Th"]:
    fits[mask] = ps.solve(ds.images, ds.lights, mask=mask, object_mask=ds.object_mask)
    ne = ps.normal_error(fits[mask].normals, ds.normals, object_mask=ds.object_mask)
    print(f"{mask or 'least squares':14s} NE {ne:.2f} deg")

# %%
# Normals coded as DiLiGenT codes them, RGB = (n + 1) / 2, and the masked fit's NE map
rows, cols = np.nonzero(ds.object_mask)
crop = np.s_[rows.min():rows.max() + 1, cols.min():cols.max() + 1]


def rgb(n):
    return np.where(ds.object_mask[..., None], (n + 1) / 2, 1)[crop]


err = ps.normal_error_map(fits["Th"].normals, ds.normals)
fig, axes = plt.subplots(1, 4, figsize=(12, 3.8), layout="constrained")
axes[0].imshow(np.clip(ds.images[0][crop] / np.percentile(ds.images[0], 99), 0, 1), cmap="gray")
axes[0].set_title("image 1")
axes[1].imshow(rgb(ds.normals))
axes[1].set_title("ground truth")
axes[2].imshow(rgb(fits["Th"].normals))
axes[2].set_title("Th")
im = axes[3].imshow(np.where(ds.object_mask, err, np.nan)[crop], cmap="magma", vmin=0, vmax=20)
axes[3].set_title("Th: NE")
fig.colorbar(im, ax=axes[3], label="NE (deg)")
for ax in axes:
    ax.axis("off")
