"""Quality factor of a mask (thesis Eq. 2.32), exported by :mod:`psbench.metrics`."""
from __future__ import annotations

import numpy as np

from .._shared.checks import PsbenchError, as_mask
from .._shared.deprecation import renamed_args

__all__ = ["quality_factor", "quality_counts"]


def _truth_masks(truth, shape):
    def get(key):
        if isinstance(truth, dict):
            return truth.get(key)
        return getattr(truth, key, None)

    hi = get("highlight")
    if hi is None:
        raise PsbenchError("truth must provide 'highlight' (k, H, W) bool "
                           "(a Scene or a dict with highlight/self_shadow/cast_shadow)")
    parts = [get("self_shadow"), get("cast_shadow")]
    parts = [p for p in parts if p is not None]
    if not parts:
        sh = get("shadow")
        if sh is None:
            raise PsbenchError("truth must provide 'self_shadow' and/or 'cast_shadow' "
                               "(or 'shadow') (k, H, W) bool")
        parts = [sh]
    out = []
    for name, arr in [("highlight", hi)] + [("shadow", p) for p in parts]:
        a = np.asarray(arr)
        if a.shape != tuple(shape):
            raise PsbenchError(f"truth.{name} must have shape {tuple(shape)} like flagged, "
                               f"got {a.shape}")
        out.append(a.astype(bool, copy=False))
    sh = out[1]
    for p in out[2:]:
        sh = sh | p
    return out[0], sh


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def quality_counts(flagged, truth, *, object_mask=None):
    """TP / FP / FN counts behind :func:`quality_factor`.

    Returns
    -------
    dict
        ``{cls: {"tp": int, "fp": int, "fn": int}}`` for ``hi``, ``sh``, ``total``.
    """
    f = np.asarray(flagged)
    if f.ndim != 3:
        raise PsbenchError(f"flagged must have shape (k, H, W), got {f.shape}")
    if f.dtype != bool:
        raise PsbenchError(f"flagged must be a bool array (e.g. ~result.valid), got {f.dtype}")
    hi, sh = _truth_masks(truth, f.shape)
    m = as_mask(object_mask, f.shape[1:], "object_mask")
    f, hi, sh = f[:, m], hi[:, m], sh[:, m]
    pos = hi | sh
    fp = int(np.count_nonzero(f & ~pos))  # false alarms: in neither class
    return {
        "hi": {"tp": int(np.count_nonzero(f & hi)), "fp": fp,
               "fn": int(np.count_nonzero(~f & hi))},
        "sh": {"tp": int(np.count_nonzero(f & sh)), "fp": fp,
               "fn": int(np.count_nonzero(~f & sh))},
        "total": {"tp": int(np.count_nonzero(f & pos)), "fp": fp,
                  "fn": int(np.count_nonzero(~f & pos))},
    }


@renamed_args(positional=("object_mask",), renamed={"mask": "object_mask"})
def quality_factor(flagged, truth, *, object_mask=None, targets=None):
    """Quality factor QF = TP / (TP + FP + FN) of a mask (Eq. 2.32).

    Counted over observations: k images x object pixels.

    Parameters
    ----------
    flagged : (k, H, W) bool
        Observations the method masked out (``~result.valid``).
    truth : Scene-like or dict
        ``highlight``, ``self_shadow``, ``cast_shadow`` (k, H, W) bool
        (or ``shadow`` instead of the two shadow maps). shadow = self | cast.
    object_mask : (H, W) bool, optional
        Object pixels to count; None = all.
    targets : iterable of {"hi", "sh"}, optional
        Classes the method is meant to detect. A class not listed is reported
        as NaN (Table 5.3's N/A, e.g. ``targets=("hi",)`` for Re); an empty
        list (None PS, CJ) makes all three NaN. Default: compute all.

    Returns
    -------
    dict
        ``hi``, ``sh``, ``total`` as floats:

        * total: positives P = highlight | shadow; TP = flagged & P,
          FN = ~flagged & P, FP = flagged & ~P.
        * hi: TP = flagged & highlight, FN = ~flagged & highlight,
          FP = flagged & ~highlight & ~shadow (false alarms that the other
          class does not explain; flagging a shadow is neither a hit nor a
          false alarm for the highlight QF).
        * sh: symmetric (TP = flagged & shadow, FN = ~flagged & shadow, same FP).

        NaN when TP + FP + FN = 0 (class empty and nothing falsely flagged);
        report it as N/A. An observation both highlight and shadow counts for
        both classes. Table 5.3's N/A for methods that do not target a class
        (e.g. Sh for "Re") is a decision by mask name: pass ``targets``.
    """
    keep = {"hi", "sh", "total"}
    if targets is not None:
        targets = {targets} if isinstance(targets, str) else set(targets)
        bad = targets - {"hi", "sh"}
        if bad:
            raise PsbenchError(f"targets may hold 'hi' and 'sh', got {sorted(bad)}")
        keep = targets | ({"total"} if targets else set())
    counts = quality_counts(flagged, truth, object_mask=object_mask)
    out = {}
    for cls, c in counts.items():
        den = c["tp"] + c["fp"] + c["fn"]
        out[cls] = c["tp"] / den if den and cls in keep else float("nan")
    return out
