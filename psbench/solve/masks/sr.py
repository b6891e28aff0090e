"""SR: secondary-reflection mask (thesis Section 8.3), a global normal mask that also
corrects the images.

The thesis closes on light that the illuminated part of a concave impression reflects
onto the rest of it, and proposes "a mask working similar to the ray tracing
algorithm ... an iterative normal mask in unified PS". Each round SR

1. integrates the current normals into heights and predicts every observation's
   secondary light by the ray casting of the renderer (:func:`psbench.solve.masks._sr.predict`,
   Lambertian emitters and receivers, on a grid of at most ``sr_size`` pixels a side);
2. masks the observations whose predicted secondary fraction ``f = secondary /
   observed`` exceeds ``t_sr`` (0.5: mostly secondary light, e.g. shadowed
   observations lit only by the rest of the surface);
3. returns the predicted secondary light as a **correction** (``sr_correct``): the
   engine solves ``images - correction`` in the next round (see *Corrections* in
   :mod:`psbench.solve.base`). Masking alone cannot remove Lambertian interreflection:
   every lit observation carries it, linearly in the light direction, so the lit
   observations agree on a wrong normal (``sr_correct=False`` keeps the literal mask
   for comparison). From the second round the correction is relaxed,
   ``(1 - sr_damp) new + sr_damp previous``, against oscillating rounds.

Options (fields of every masked method's options, ``options.sr_*`` on the command
line): ``sr_samples``, ``sr_size``, ``sr_damp``, ``sr_correct``, ``sr_bounces``,
``sr_source`` (see :class:`psbench.solve.base.Options`); the engine stops once a round
moves the normals by less than ``correct_tol`` degrees. Limits: the prediction is
Lambertian (see :mod:`psbench.solve.masks._sr` for what that costs on specular images);
where the rounds do not converge they magnify last-bit differences of the weighted
solves, e.g. between one and two BLAS threads (docs: *Compiled kernels and threads*).
"""
from __future__ import annotations

import numpy as np

from ...registry import Mask, Threshold
from .. import kernel

__all__ = ["apply", "MASK"]


def _change(n0, n1, omask):
    """Mean angle (degrees) between two normal maps over the object."""
    c = np.einsum("hwc,hwc->hw", n0, n1)[omask]
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))).mean()) if c.size else 0.0


def apply(images, b, ctx):
    """Global normal stage with a correction: ``(valid, secondary light or None)``.

    ``images`` are the corrected images of the previous round; the secondary fraction
    is measured against the observed ones (``ctx.images``). State across rounds (the
    previous prediction, normals and validity) lives in ``ctx.state["SR"]``.
    """
    from ._sr import predict, sr_valid

    o = ctx.options
    st = ctx.state.setdefault("SR", {})
    prev = st.get("normals")
    if prev is None:  # the first prediction from all observations (see the notes)
        b = kernel.ls(ctx.images, ctx.S)
    normals = kernel.split(b)[0]
    # the rounds in which the normals still move by degrees use half the azimuths: the
    # quadrature's error is then far below that of the normals; once fine, stay fine
    moving = prev is None or _change(prev, normals, ctx.object_mask) > 1.0
    st["fine"] = fine = st.get("fine", False) or not moving
    samples = o.sr_samples if fine else max(8, o.sr_samples // 2)
    pred = predict(b, ctx.lights, object_mask=ctx.object_mask, images=ctx.images,
                   valid=st.get("valid"), source=o.sr_source, bounces=o.sr_bounces,
                   samples=samples, size=o.sr_size,
                   sh_bias=0.5 if o.sh_bias is None else o.sh_bias)
    valid = sr_valid(pred, t_sr=ctx.thresholds["t_sr"])
    sec = pred.secondary
    last = st.get("secondary")
    if last is not None and o.sr_damp > 0:
        sec *= np.float32(1.0 - o.sr_damp)
        sec += np.float32(o.sr_damp) * last
    st.update(normals=normals, valid=valid, secondary=sec)
    return valid, (sec if o.sr_correct else None)


MASK = Mask("SR", "normal", apply, local=False,
            thresholds=(Threshold("t_sr", 0.5, (0.0, 1.0),
                                  help="SR: mask observations whose predicted secondary "
                                       "fraction exceeds this"),),
            help="secondary reflections: ray-cast interreflection predicted from the "
                 "integrated normals, masked above t_sr and subtracted (Section 8.3)")
