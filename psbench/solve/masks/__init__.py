"""The masks of the unified PS (Chapter 3), one module per mask.

=======  =======  ======================================================  ==========
module   token    what it masks                                           stage
=======  =======  ======================================================  ==========
th       Th       shadows / highlights by image range (Eq. 3.2)           image
nl       NL       non-Lambert quadruple, 4 images (Eqs. 3.3-3.6)          image
xnl      xNL      sorted consecutive quadruples, k >= 4 (3.3.3.2)         subset
ra       RA       RANSAC over image triplets (3.3.3.3)                    subset
cj       CJ       Coleman-Jain, 4 images; fuses its own solution          subset
ss       SS       self shadows s.n <= 0 (Eq. 3.7)                         normal
re       Re       normal near a light/view bisector (Eq. 3.8)             normal
cs       CS       darker than the Lambert prediction (Eq. 3.9)            normal
hi       Hi       brighter than the Lambert prediction (Eq. 3.10)         normal
sh       Sh       shadow maps of the integrated normals (3.3.2.5)         normal
=======  =======  ======================================================  ==========

Each module exposes ``MASK`` (a :class:`psbench.registry.Mask`) and its maths
functions; the stage contracts are in :mod:`psbench.solve.base`. They are
registered through the ``psbench.masks`` entry-point group (psbench's
``pyproject.toml``), exactly as another package registers its own masks. Every
function returns **validity** (True = observation used, the thesis's F = 1).

Writing a mask: one module with ``MASK = Mask(name, stage, func, ...)`` and an entry
point ``MyMask = "mypkg.mymask:MASK"`` under ``[project.entry-points."psbench.masks"]``
(or ``psbench.registry.register("masks", MASK)`` at run time).

``ranges`` and ``SCOPES`` (the dynamic ranges behind ``th_scope``) stay importable
from here.
"""
from ._ranges import SCOPES, ranges

__all__ = ["SCOPES", "ranges"]
