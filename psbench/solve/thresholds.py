"""Mask thresholds: Table 5.2 and their resolution for any image count.

Every mask declares the thresholds it reads (:class:`psbench.registry.Threshold`:
name, default, valid range); :func:`resolve_thresholds` resolves every declared
threshold of every registered mask, so a plug-in mask's threshold is overridable
exactly like Table 5.2's. Table 5.2 of the thesis lists tuned thresholds for 4, 6, 8
and 12 images (the built-in masks declare these columns):

=========  =====  =====  =====  =====
name         4      6      8     12
=========  =====  =====  =====  =====
k_low       0.02   0.06   0.06   0.08
k_up        0.35   0.35   0.35   0.35
k_Hi        0.03   0.04   0.05   0.06
k_CS       -0.10  -0.10  -0.10  -0.10
t_NL        0.02   0.04   0.02   0.01
t_Re       min(z, (90 - z)/2, p)   (Eq. 5.1, degrees)
=========  =====  =====  =====  =====

Decisions (psbench):

* **Between table columns** the values are linearly interpolated in the image count k
  (e.g. k = 5 takes the mean of the 4 and 6 columns; k = 16 is beyond the table).
  **Beyond the table** they are clamped: k < 4 uses column 4, k > 12 uses column 12.
  The same rule reads any threshold declared per image count (``Threshold.counts``).
* **t_Re** follows Eq. 5.1 per light: z is that light's zenith and p the polar spacing
  of the layout seen from above (the smallest polar difference between any two lights
  of the whole layout, e.g. 45 deg for ``45x8``, 22.5 deg for ``30x8+60x8``). For
  multi-ring layouts every light gets its own t_Re (its own z); the resolved dict holds
  a float when all lights agree and a tuple of k floats otherwise.
* ``t_RA`` (RANSAC consensus threshold, fraction of the mean dynamic range) and
  ``t_CJ`` (Coleman-Jain threshold on std/mean of the four triplet albedos) are not
  in Table 5.2; they default to the subset module's values
  (:data:`psbench.solve.subset.RA_THRESHOLD` = 0.1, ``CJ_THRESHOLD`` = 0.1).
* Two masks may declare the same threshold (Th and NL read k_low) with the same spec.

All values are overridable per run (``solve(..., thresholds={"k_low": 0.1})``); unknown
names or out-of-range values raise :class:`psbench.PsbenchError`, and ``k_low`` must
stay below ``k_up``. ``NAMES`` and ``RANGES`` list the declared thresholds (read from
the registry when accessed).
"""
from __future__ import annotations

import warnings

import numpy as np

from .._shared.checks import PsbenchError
from ._specs import mask_specs

__all__ = ["TABLE_5_2", "COUNTS", "NAMES", "RANGES", "declared", "resolve_thresholds",
           "t_re", "eq_5_1", "polar_spacing", "t_re_array"]

#: image counts of Table 5.2's columns
COUNTS = (4, 6, 8, 12)

#: Table 5.2 values per column (the defaults the built-in masks declare)
TABLE_5_2 = {
    "k_low": (0.02, 0.06, 0.06, 0.08),
    "k_up": (0.35, 0.35, 0.35, 0.35),
    "k_Hi": (0.03, 0.04, 0.05, 0.06),
    "k_CS": (-0.1, -0.1, -0.1, -0.1),
    "t_NL": (0.02, 0.04, 0.02, 0.01),
}


def __getattr__(name):  # NAMES, RANGES: computed from the registry when read
    if name == "RANGES":
        return {n: t.range for n, t in declared().items()}
    if name == "NAMES":
        return tuple(declared())
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def declared(masks=None) -> dict:
    """Every threshold the registered masks declare (or ``masks``, name -> Mask),
    name -> Threshold (first declaration wins; a conflicting redeclaration warns)."""
    out, owner = {}, {}
    for mname, spec in (mask_specs() if masks is None else masks).items():
        for t in spec.thresholds:
            prev = out.get(t.name)
            if prev is None:
                out[t.name], owner[t.name] = t, mname
            elif prev is not t and prev != t:
                warnings.warn(f"psbench: mask {mname!r} declares threshold {t.name!r} "
                              f"differently from mask {owner[t.name]!r}; keeping the latter",
                              RuntimeWarning, stacklevel=3)
    return out


def polar_spacing(lights) -> float:
    """Smallest polar-angle difference (degrees) between any two lights of a layout.

    Lights at zenith ~0 have no defined polar angle and are ignored; a layout with
    fewer than two tilted lights returns 90.
    """
    pol = np.asarray(lights.polar, dtype=float)[np.asarray(lights.zenith) > 1e-6]
    if pol.size < 2:
        return 90.0
    p = np.sort(np.unique(np.round(pol % 360.0, 9)))
    if p.size < 2:
        return 90.0  # all lights at one polar angle (e.g. rings stacked above each other)
    gaps = np.diff(np.concatenate([p, [p[0] + 360.0]]))
    return float(gaps.min())


def t_re(lights) -> np.ndarray:
    """Eq. 5.1 per light: ``min(z, (90 - z) / 2, p)`` in degrees, shape (k,)."""
    z = np.asarray(lights.zenith, dtype=float)
    p = polar_spacing(lights)
    return np.minimum(np.minimum(z, (90.0 - z) / 2.0), p)


def eq_5_1(k, lights):
    """Default of t_Re (Eq. 5.1), or None without a layout."""
    return None if lights is None else t_re(lights)


def _default(t, k, lights):
    d = t.default
    if callable(d):
        d = d(k, lights)
        return None if d is None else _compact(d)
    if isinstance(d, (tuple, list)) and t.counts is not None:
        return float(np.interp(k, t.counts, d))  # np.interp clamps beyond the ends
    return float(d) if isinstance(d, (int, float)) else _compact(d)


def resolve_thresholds(k, lights=None, overrides=None, *, masks=None) -> dict:
    """Resolve the thresholds used for ``k`` images.

    Parameters
    ----------
    k : int
        Number of images.
    lights : Layout, optional
        Needed for t_Re (Eq. 5.1); without it t_Re is left to ``overrides`` or None.
    overrides : dict, optional
        Values replacing the defaults, keyed by :data:`NAMES`. A per-light threshold
        (``t_Re``) may be a scalar or a sequence of k values.
    masks : dict, optional
        name -> Mask whose thresholds to resolve (default: every registered mask).

    Returns
    -------
    dict
        Every declared threshold: ``k_low, k_up, k_Hi, k_CS, t_NL`` (float), ``t_Re``
        (float or tuple of k floats, degrees), ``t_RA``, ``t_CJ`` (float), and those
        of plug-in masks.
    """
    k = int(k)
    decl = declared(masks)
    out = {name: _default(t, k, lights) for name, t in decl.items()}
    if overrides is None:
        overrides = {}
    if not isinstance(overrides, dict):
        raise PsbenchError(f"thresholds must be a dict of name -> value, got {type(overrides).__name__}")
    for name, value in overrides.items():
        if name not in decl:
            raise PsbenchError(
                f"thresholds: unknown name {name!r}; valid names: {', '.join(decl)}")
        if value is None:
            raise PsbenchError(f"thresholds[{name!r}] must be a number, got None")
        lo, hi = decl[name].range
        per_light = decl[name].per_light
        arr = np.asarray(value, dtype=float) if not isinstance(value, str) else None
        if arr is None or arr.ndim > 1 or (arr.ndim == 1 and (not per_light or arr.shape[0] != k)):
            want = f"a number or {k} numbers" if per_light else "a number"
            raise PsbenchError(f"thresholds[{name!r}] must be {want}, got {value!r}")
        if not np.isfinite(arr).all() or (arr < lo).any() or (arr > hi).any():
            raise PsbenchError(
                f"thresholds[{name!r}]={value!r} is out of range; expected {lo:g} <= value <= {hi:g}")
        out[name] = _compact(arr) if arr.ndim == 1 else float(arr)
    if "k_low" in out and "k_up" in out and out["k_low"] >= out["k_up"]:
        raise PsbenchError(
            f"thresholds: k_low={out['k_low']:g} must be below k_up={out['k_up']:g}")
    return out


def _compact(arr):
    arr = np.asarray(arr, dtype=float)
    if arr.ndim == 0:
        return float(arr)
    if np.allclose(arr, arr[0]):
        return float(arr[0])
    return tuple(float(x) for x in arr)


def t_re_array(thresholds, k) -> np.ndarray:
    """The resolved t_Re as a (k,) float array (degrees)."""
    t = thresholds.get("t_Re")
    if t is None:
        raise PsbenchError("t_Re is unknown: pass lights or thresholds={'t_Re': ...}")
    return np.broadcast_to(np.asarray(t, dtype=float), (k,)).copy()
