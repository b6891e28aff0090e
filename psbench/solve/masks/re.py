"""Re: reflection mask (Eq. 3.8, corrected).

Eq. 3.8 prints the masked and kept cases inverted; psbench masks observation i where
the angle between the normal and the bisector of light i and the view direction
(0, 0, 1) is below t_Re (Eq. 5.1 per light, degrees).
"""
from __future__ import annotations

from ...registry import Mask
from .. import kernel
from ._shared import T_RE, reflection_valid

__all__ = ["apply", "MASK"]


def apply(images, b, ctx):
    """Local normal stage."""
    n, _ = kernel.split(b.reshape(1, -1, 3) if b.ndim == 2 else b)
    return reflection_valid(n.reshape(b.shape), ctx.directions, ctx.t_re())


MASK = Mask("Re", "normal", apply, thresholds=(T_RE,),
            help="specular directions: normal within t_Re of a light/view bisector (Eq. 3.8)")
