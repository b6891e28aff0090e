"""Unified photometric stereo (Chapter 3): :func:`solve`.

``solve`` validates its input, parses the mask expression against the
``psbench.masks`` registry, builds the method's options from the ``psbench.methods``
registry and hands over to the mask engine (:mod:`psbench.solve._engine`, Fig. 3.1).
The stage contracts of masks and methods are in :mod:`psbench.solve.base`.

Mask names are joined by '-' (whitespace also accepted); a combination is the logical
AND of validity. See the modules of :mod:`psbench.solve.masks` for the per-mask
decisions (Th offset, range scopes, NL rule, Re/SS sign corrections) and
:mod:`psbench.solve.thresholds` for Table 5.2 and its interpolation.

Degenerate input: all-zero images give normals (0, 0, 1), albedo 0 and a
RuntimeWarning; images with zero dynamic range (each image constant) make the
range-based masks (Th, Hi, CS, NL) mask nothing (strict bounds) and warn -- such a
stack is a plane under distant lights, which least squares solves exactly.

``MASKS``, ``METHODS``, ``OPTIONS`` and ``IMAGE_MASKS`` / ``SUBSET_MASKS`` /
``NORMAL_MASKS`` are read from the registries when accessed (plug-ins included).
"""
from __future__ import annotations

import warnings
from dataclasses import fields

from .. import registry
from .._shared.checks import PsbenchError, as_images, as_mask, as_normals
from .._shared.memory import managed_memory
from . import _engine
from ._result import Result, Timer
from ._specs import check_counts, mask_names, mask_specs, method_names
from .thresholds import resolve_thresholds

__all__ = ["solve", "Result", "MASKS", "METHODS", "parse_mask", "OPTIONS"]

#: keyword arguments of :func:`solve` that map onto a method's options
_EXPLICIT = ("max_iter", "th_scope", "weighted", "weight", "binary")


def __getattr__(name):  # compatibility names, computed from the registries when read
    if name == "MASKS":
        return mask_names()
    if name == "METHODS":
        return method_names()
    if name in ("IMAGE_MASKS", "SUBSET_MASKS", "NORMAL_MASKS"):
        stage = name.split("_")[0].lower()
        return tuple(n for n, s in mask_specs().items() if s.stage == stage)
    if name == "OPTIONS":
        out = {}
        for spec in registry.methods().values():
            for f in fields(spec.options):
                if f.name not in _EXPLICIT:
                    out.setdefault(f.name, f.default)
        return out
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def parse_mask(mask, *, specs=None) -> tuple[str, ...]:
    """Split a mask name into canonical tokens ('th-hi' -> ('Th', 'Hi')); () for None.

    ``specs``: name -> Mask to parse against (default: the registered masks)."""
    if mask is None:
        return ()
    if isinstance(mask, (list, tuple)):
        parts = [str(p) for p in mask]
    elif isinstance(mask, str):
        parts = mask.replace("-", " ").replace("+", " ").split()
    else:
        raise PsbenchError(f"mask must be a string like 'Th-Hi-Re-Sh', got {type(mask).__name__}")
    specs = mask_specs() if specs is None else specs
    canon = {n.lower(): n for n in specs}
    canon["none"] = "None"
    out = []
    for p in parts:
        c = canon.get(p.strip().lower())
        if c is None:
            raise PsbenchError(
                f"mask={mask!r}: unknown mask {p!r}; valid masks: {', '.join(('None', *specs))} "
                "(combine with '-', e.g. 'Th-Hi-Re-Sh')")
        if c != "None" and c not in out:
            out.append(c)
    fusing = [t for t in out if specs[t].fuses]
    if fusing and len(out) > 1:
        raise PsbenchError(f"mask={mask!r}: {fusing[0]} fuses its own solution and cannot be "
                           f"combined with other masks; use mask={fusing[0]!r}")
    return tuple(out)


def _layout(lights, k):
    from ..lights import Layout, layout
    try:
        lay = lights if isinstance(lights, Layout) else layout(lights)
    except PsbenchError:
        raise
    except Exception as exc:  # e.g. ragged lists
        raise PsbenchError(f"lights must be a Layout, a (k, 3) array or ring notation like "
                           f"'45x8'; got {lights!r:.80} ({exc})") from None
    if lay.k != k:
        raise PsbenchError(f"lights has {lay.k} lights ({lay.name}) but images holds {k} images; "
                           "they must match one to one")
    return lay


def _options(spec, explicit, opts):
    """The method's options from solve()'s keywords; ``weight`` / ``binary`` reach only a
    method that has them (as before: they are WPS's)."""
    names = spec.options.__dataclass_fields__
    values = {k: v for k, v in explicit.items() if k in names or k not in ("weight", "binary")}
    values.update(opts)
    return spec.options.build(values, method=spec.name)


@managed_memory
def solve(images, lights, *, mask="None", method="ps", weighted=False, object_mask=None,
          thresholds=None, max_iter=10, seed=0, weight=None, binary=False, want_height=False,
          truth_normals=None, th_scope="image", **opts) -> Result:
    """Unified photometric stereo with masks (Chapter 3).

    Parameters
    ----------
    images : (k, H, W) array_like
        k >= 3 linear images; unsigned integers are converted to [0, 1]; NaN refused.
    lights : Layout, (k, 3) array_like or str
        Light layout (``"45x8"``); its count must match the images.
    mask : str
        Registered mask tokens joined by '-': None, Th, NL, xNL, SS, Re, CS, Hi, Sh,
        CJ, RA (NL and CJ need k = 4) and those of plug-ins.
    method : str
        A registered method: "ps" (masked least squares), "fwlse" (feasible WLS,
        Section 3.4.1, started from the masked solution), "wps" (weighted multi-zenith
        PS, :mod:`psbench.solve.methods.wps`), or a plug-in's.
    weighted : bool
        Weighted masks (Section 3.4.2, Eq. 3.19) after the binary solve (WPS: in every
        ring's solve).
    object_mask : (H, W) bool, optional
        Pixels of the object (ranges of th_scope "object"/"robust"/"pixel", Sh
        integration, outputs). Default: all pixels.
    thresholds : dict, optional
        Overrides of the masks' declared thresholds (Table 5.2; see
        :func:`psbench.solve.thresholds.resolve_thresholds`).
    max_iter : int
        Maximum PS <-> normal-mask rounds (and FWLSE iterations); >= 0.
    seed : int
        RANSAC seed.
    weight, binary
        Options of the methods that have them ("wps"); ignored by the others.
    want_height : bool
        Integrate the final normals (``integrator``) into ``Result.height``.
    truth_normals : (H, W, 3), optional
        Only for diagnostics: records the mean normal error per round in ``info["ne"]``.
    th_scope : {"image", "object", "robust", "pixel"}
        How the dynamic ranges of Th / Hi / CS are measured (see
        :mod:`psbench.solve.masks._ranges`). "image" is the thesis's rule.
    **opts
        Further fields of the method's options class (:class:`psbench.solve.base.Options`
        and the method's own): ``dilate_radius`` (7), ``smooth_sigma`` (3),
        ``kernel_size`` (15), ``sigma_min`` (None = 1 % of the mean dynamic range),
        ``th_offset`` (False: literal Eq. 3.2; True: Th bounds offset by i_min),
        ``sh_bias`` (shadow-map bias, None = shadowmap default), ``integrator``
        ("poisson"; formerly ``integrate_method``), ``n_subsets`` (RA), ``iter_tol`` (1e-3: also stop after a round that
        changed the mask of at most this fraction of the object pixels; 0: iterate
        until no mask changes, a cycle, or ``max_iter``); "fwlse": ``fwlse_tol``;
        "wps": ``z_scale``. Unknown names are refused, listing the valid ones. With Sh
        the masks of a few hundred shadow-boundary pixels keep drifting on large
        images (the integrated heights shift slightly each round; at 2048^2: 70133,
        3087, 668, 372, 328, ... changed pixels per round, NE changing by < 0.001 deg
        per round), so exact convergence would run every remaining round at full Sh
        cost.

    Returns
    -------
    Result
        (``WPSResult`` for "wps".)
    """
    timer = Timer()
    images = as_images(images, "images", min_count=3)
    k, H, W = images.shape
    lay = _layout(lights, k)
    masks = mask_specs()
    tokens = parse_mask(mask, specs=masks)
    spec = registry.get("methods", method, what="method")
    options = _options(spec, dict(max_iter=max_iter, th_scope=th_scope, weighted=weighted,
                                  weight=weight, binary=binary), opts)
    check_counts(tokens, k, mask, masks)
    glob = [t for t in tokens if masks[t].stage == "normal" and not masks[t].local]
    if (glob or want_height) and min(H, W) < 2:
        what = " and ".join([f"the {t} mask" for t in glob] + ["want_height"] * want_height)
        raise PsbenchError(f"images of {H}x{W} pixels: {what} integrate heights and need at "
                           "least 2x2 pixels")
    omask = as_mask(object_mask, (H, W), "object_mask")
    if not omask.any():
        raise PsbenchError("object_mask selects no pixel")
    if truth_normals is not None:
        truth_normals = as_normals(truth_normals, "truth_normals", (H, W))
    thr = resolve_thresholds(k, lay, thresholds, masks=masks)
    timer.lap("validate")
    # a solver's warnings (non-convergence, ...) are reported at the caller's line, not
    # at a line inside psbench (the line Python prints beside the message)
    pending = []
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                return _engine.run(images, lay, tokens=tokens, thresholds=thr,
                                   options=options, object_mask=omask, seed=seed, method=spec,
                                   overrides=thresholds, want_height=want_height,
                                   truth=truth_normals, timer=timer, masks=masks)
            finally:
                pending = list(caught)
    finally:                            # the caller's filters apply to these
        for w in pending:
            warnings.warn(w.message, w.category, stacklevel=2)
