"""The registered masks and methods, in a stable presentation order.

Built-in masks come in the thesis's order (Table 5.3 / Fig. 3.1: image, subset and
normal masks as the thesis introduces them); masks of other packages follow,
sorted by name. The order only affects listings and error messages: a mask
expression is an AND, so token order never changes a result.
"""
from __future__ import annotations

from .. import registry
from .._shared.checks import PsbenchError

#: presentation order of psbench's own masks
THESIS_ORDER = ("Th", "NL", "xNL", "SS", "Re", "CS", "Hi", "Sh", "CJ", "RA")


def _key(name):
    return (0, THESIS_ORDER.index(name), "") if name in THESIS_ORDER else (1, 0, name.lower())


_ORDER_CACHE: dict = {}


def mask_specs() -> dict:
    """name -> :class:`psbench.registry.Mask`, in presentation order."""
    specs = registry.masks()
    names = tuple(specs)
    order = _ORDER_CACHE.get(names)
    if order is None:
        order = _ORDER_CACHE[names] = tuple(sorted(names, key=_key))
    return {n: specs[n] for n in order}


def mask_names() -> tuple[str, ...]:
    """"None" and every registered mask name (the valid mask tokens)."""
    return ("None",) + tuple(mask_specs())


def method_names() -> tuple[str, ...]:
    """Every registered method name (psbench's own first: ps, fwlse, wps)."""
    own = ("ps", "fwlse", "wps")
    names = registry.names("methods")
    return tuple(n for n in own if n in names) + tuple(n for n in names if n not in own)


def check_counts(tokens, k, expr, specs=None):
    """Refuse a mask of the expression that does not accept ``k`` images."""
    specs = mask_specs() if specs is None else specs
    for t in tokens:
        lo, hi = specs[t].images
        if k < lo or (hi is not None and k > hi):
            need = (f"exactly {lo}" if hi == lo else f"at least {lo}" if hi is None
                    else f"{lo} to {hi}")
            hint = f" ({t}: {specs[t].help})" if specs[t].help else ""
            raise PsbenchError(f"mask={expr!r}: {t} needs {need} images, got {k}{hint}")
