"""
A masked solve on a rendered scene
==================================

Render the sombrero under 16 lights on two rings with Torrance-Sparrow highlights, cast
shadows and 5 % noise, then solve it without a mask, with the threshold mask ``Th`` and
with the combination ``Th-Hi-Re-Sh`` (threshold AND highlight AND reflection AND shadow
masks, iterated with PS until the masks settle). The normal error (NE, mean angle to the
true normals) says what each mask buys; the maps show where.
"""
import matplotlib.pyplot as plt
import numpy as np

import psbench as ps

surf = ps.make_surface("sombrero2", size=128)
lay = ps.layout("30x8+60x8")
scene = ps.render(surf, lay, model="ts", noise=0.01, seed=0)

masks = ["None", "Th", "Th-Hi-Re-Sh"]
results = {m: ps.solve(scene.images, lay, mask=m, object_mask=surf.object_mask) for m in masks}
for m, res in results.items():
    ne = ps.normal_error(res.normals, surf.normals, object_mask=surf.object_mask)
    print(f"{m:12s} NE {ne:5.2f} deg   observations used {res.valid[:, surf.object_mask].mean():.0%}")

# %%
# Per-pixel normal error, on one colour scale (degrees)
fig, axes = plt.subplots(1, len(masks), figsize=(10, 3.6), layout="constrained")
for ax, (m, res) in zip(axes, results.items()):
    err = ps.normal_error_map(res.normals, surf.normals)
    im = ax.imshow(np.where(surf.object_mask, err, np.nan), cmap="magma", vmin=0, vmax=20)
    ax.set_title(m)
    ax.axis("off")
cbar = fig.colorbar(im, ax=axes, label="NE (deg)", shrink=0.9)

# %%
# What ``Th-Hi-Re-Sh`` excluded in one image (white) beside the true highlights and
# shadows the renderer reports
i = 3
res = results["Th-Hi-Re-Sh"]
truth = scene.highlight[i] | scene.self_shadow[i] | scene.cast_shadow[i]
panels = [(scene.images[i], f"image {i} (zenith {lay.zenith[i]:.0f} deg)"),
          (~res.valid[i] & surf.object_mask, "excluded by the mask"),
          (truth & surf.object_mask, "true highlight or shadow")]
fig, axes = plt.subplots(1, 3, figsize=(10, 3.4), layout="constrained")
for ax, (img, title) in zip(axes, panels):
    ax.imshow(img, cmap="gray")
    ax.set_title(title)
    ax.axis("off")
