"""
A cartridge case (Chapter 7)
============================

Two fired cartridge cases from the same gun (sisters) and one from another gun, rendered
by the Chapter 7 rig (16 lights ``31x8+62x8``, brass, 8-bit), reconstructed with weighted
``Th-Hi-Re-Sh`` and bilateral integration, and compared the way examiners compare
breech-face impressions: the areal CCFmax after a band-pass and registration. Small
(256 x 256, 19.6 µm per pixel) so it runs in seconds.
"""
import matplotlib.pyplot as plt
import numpy as np

import psbench as ps
from psbench.forensic import acquire, compare, make_cartridge

size = 256
reference = make_cartridge(size, gun=3, case=3)
sister = make_cartridge(size, gun=3, case=5)
other = make_cartridge(size, gun=4, case=5)


def reconstruct(case):
    acq = acquire(case)
    res = ps.solve(acq.images, acq.lights, mask="Th-Hi-Re-Sh", weighted=True,
                   object_mask=case.object_mask)
    z = ps.integrate(res.normals, object_mask=case.object_mask, integrator="bilateral")
    return acq, z * case.pixel_size  # heights in µm


bf_ref = reference.regions["breech_face"]
results = {}
for name, case in [("sister", sister), ("other gun", other)]:
    acq, z = reconstruct(case)
    m = compare(reference.height_um, z, bf_ref, case.regions["breech_face"],
                pixel_size=case.pixel_size)
    results[name] = (acq, z)
    print(f"{name:10s} CCFmax {m.ccf:.2f}  rotation {m.angle:5.1f} deg")

# %%
# One of the 16 images, and the breech-face topography the comparison sees (heights
# band-passed 16-250 µm, inside the breech-face region): the reference case's true
# heights beside the sister's reconstruction
from psbench.forensic import bandpass

acq, z = results["sister"]
bf_sis = sister.regions["breech_face"]
panels = [(bandpass(reference.height_um, bf_ref, pixel_size=reference.pixel_size), bf_ref,
           "reference, true (band-passed)"),
          (bandpass(z, bf_sis, pixel_size=sister.pixel_size), bf_sis,
           "sister, reconstructed (band-passed)")]
fig, axes = plt.subplots(1, 3, figsize=(12, 4), layout="constrained")
axes[0].imshow(acq.images[0], cmap="gray")
axes[0].set_title("sister: image 1 of 16 (8-bit)")
for ax, (h, region, title) in zip(axes[1:], panels):
    rows, cols = np.nonzero(region)
    h = np.where(region, h, np.nan)[rows.min():rows.max() + 1, cols.min():cols.max() + 1]
    lim = np.nanpercentile(np.abs(h), 99)
    im = ax.imshow(h, cmap="RdBu_r", vmin=-lim, vmax=lim)
    ax.set_title(title)
    fig.colorbar(im, ax=ax, label="height (µm)", shrink=0.8)
for ax in axes:
    ax.axis("off")
