"""The recipe psbench recommends for breech-face heights: :func:`reconstruct_heights`.

Why the thesis's masks lose margin on real marks. Measured on the shared Weller scans
rendered with the Chapter 7 acquisition (31x8+62x8, 8-bit, mean level 75/255, brass
and nickel presets), Poisson heights compared with the scan after band-passing:

- The loss comes from exposure and Th, not from the marks. :func:`psbench.forensic.
  acquire` meters the mean level on the whole frame; a scan's data covers about a
  third of it (the rest renders black), so the face is exposed ~3x brighter and the
  nearly flat face, seen by every 31° light close to its mirror direction, clips:
  27-80 % of each 31° image's face pixels (TW01-01, TW04-03, TW08-05, TW11-02: brass
  0.47-0.80, nickel 0.26-0.59), the 62° images at most 0.2 %. Th (Eq. 3.2, ``k_up``
  = 0.35 of each image's range) then drops 81 % of all observations of TW01-01 brass,
  both rings alike (31°: 79 %, 62°: 84 %), and only 7.7 % of what it drops are true
  highlights or shadows of the render; pixels left with < 3 observations fall back to
  the three of least residual. The fine marks suffer most: correlation with the scan
  in 16-60 µm 0.968 (least squares) -> 0.919 (Th-Hi-Re-Sh); 60-500 µm 0.995 -> 0.978.
- Metered on the face (``breechface.render_scan(meter="object")``) nothing clips, Th
  drops the 31° ring (93 %) and keeps the 62° one (1.2 % dropped): Th-Hi-Re-Sh and
  least squares then correlate alike with the scan (16-60 µm: 0.972 both), but least
  squares' heights are 5x off in amplitude (mean |error| 1.20 µm vs 0.24 µm): the
  specular 31° observations tilt the normals.
- The reflection mask Re alone drops the 31° ring under both exposures (90-91 %) and
  keeps the fine marks (16-60 µm: 0.972 frame-metered, 0.971 face-metered; error 0.25
  / 0.26 µm).

The recipe: leave out the overexposed *images* (more than ``max_clipped`` of the face
clipped), then masked least squares with Re on the rest, Poisson, times the pixel size.

Defaults and their basis:

- ``max_clipped`` = 0.05: on the shared scans the clipped fractions per image are
  bimodal (<= 0.2 % or >= 26 %), so any value in between makes the same choice; 5 %
  leaves room for the glints of rougher marks. Clipped = at full scale (the dtype's
  maximum; 1.0 for float images): saturated observations carry no information.
- ``mask`` = "Re" with the thesis's Table 5.2 threshold: the variant that kept the
  fine marks and the amplitude under both exposure rules (numbers above).
- Poisson integration over ``object_mask``: heights in µm, offset arbitrary.

Checked afterwards on all 95 shared scans (experiment ``breechface``, brass, Poisson,
4,465 pairs): AUC 1.000 (CMC and CCFmax) as for the scans, 0 false positives and 0
false negatives at 6 cells (scans: 0 and 0), CMC separation 13 (scans 14), CCF
separation 0.530 (scans 0.499; least squares 0.505, WPS 0.502, robust 0.463,
Th-Hi-Re-Sh 0.429). With the bilateral integrator and on nickel it is the same: AUC
1.000, no false positive or negative; CCF separation 0.533 (brass, bilateral; least
squares 0.505), 0.521 and 0.527 (nickel, Poisson and bilateral; least squares 0.525 with
both). None of the defaults above was changed for it.
"""
from __future__ import annotations

import numpy as np

from .._shared.checks import PsbenchError, as_images, as_mask
from ..integrate import integrate
from ..lights import layout as _layout
from ..solve import solve
from .cartridge import check_pixel_size

__all__ = ["MAX_CLIPPED", "reconstruct_heights", "clipped_fractions"]

#: an image with a larger fraction of clipped object pixels is left out
MAX_CLIPPED = 0.05


def _directions(lights, k):
    if isinstance(lights, str):
        lights = _layout(lights)
    S = np.asarray(getattr(lights, "directions", lights), np.float64)
    if S.shape != (k, 3) or not np.isfinite(S).all():
        raise PsbenchError(f"lights must be a Layout or a ({k}, 3) array of finite "
                           f"directions for {k} images, got shape {S.shape}")
    return S


def clipped_fractions(images, object_mask=None):
    """Fraction of each image's object pixels at full scale, shape (k,).

    Full scale is the dtype's maximum for unsigned images, 1.0 for float images.
    """
    arr = np.asarray(images)
    full = np.iinfo(arr.dtype).max if np.issubdtype(arr.dtype, np.unsignedinteger) else 1.0
    m = as_mask(object_mask, arr.shape[1:], "object_mask")
    return (arr[:, m] >= full).mean(1) if m.any() else np.zeros(len(arr))


def reconstruct_heights(images, lights, *, object_mask, pixel_size, max_clipped=MAX_CLIPPED,
                        mask="Re", integrator="poisson"):
    """Breech-face heights (µm) from a PS capture: psbench's forensic recipe.

    Parameters
    ----------
    images : (k, H, W) array_like
        The camera images (unsigned integers: full scale is the dtype's maximum; floats:
        1.0), k >= 3.
    lights : Layout, (k, 3) array_like or str
    object_mask : (H, W) bool
        The region to reconstruct (the breech face).
    pixel_size : float
        µm per pixel.
    max_clipped : float, default 0.05
        Images with more than this fraction of clipped object pixels are left out
        (see the module's notes for the numbers behind it).
    mask : str, default "Re"
        Mask expression of :func:`psbench.solve` on the images kept: the reflection
        mask (Eq. 3.8), which drops the observations near the mirror direction.
    integrator : str, default "poisson"
        :func:`psbench.integrate` method.

    Returns
    -------
    (H, W) float32
        Heights in µm (offset arbitrary), 0 outside ``object_mask``.
    """
    ps = check_pixel_size(pixel_size)
    raw = np.asarray(images)
    I = as_images(raw, "images", min_count=3)
    k = len(I)
    S = _directions(lights, k)
    m = as_mask(object_mask, I.shape[1:], "object_mask")
    if not m.any():
        raise PsbenchError("object_mask must select at least one pixel")
    if not 0 <= float(max_clipped) <= 1:
        raise PsbenchError(f"max_clipped must be in [0, 1], got {max_clipped!r}")
    frac = clipped_fractions(raw, m)
    use = frac <= float(max_clipped)
    if use.sum() < 3:                     # too few well-exposed images: keep them all
        use[:] = True
    res = solve(np.ascontiguousarray(I[use]), S[use], mask=mask, object_mask=m)
    normals = res.normals
    h = integrate(normals, object_mask=m, integrator=integrator)
    return np.where(m, h * np.float32(ps), 0.0).astype(np.float32)
