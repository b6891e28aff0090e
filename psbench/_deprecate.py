"""Deprecation helpers: old argument forms keep working for one release, with a warning.

psbench's public functions take their arrays positionally and every option by keyword,
and the object region is ``object_mask`` everywhere (``mask`` names the mask expression
of :func:`psbench.solve` only). :func:`renamed_args` keeps the earlier call forms
working behind a :class:`DeprecationWarning` that points at the caller's line:

* options that used to be accepted positionally (``normal_error(n, t, m)``);
* keyword arguments that were renamed (``integrate(n, mask=m)``).

The result is the same as with the new form; only the warning differs.
"""
from __future__ import annotations

import functools
import inspect
import warnings

__all__ = ["renamed_args", "warn_renamed"]

#: release in which the old forms go away
REMOVED_IN = "0.3"


def warn_renamed(old, new, *, stacklevel=3):
    """Warn that ``old`` is deprecated in favour of ``new``."""
    warnings.warn(f"{old} is deprecated and will be removed in psbench {REMOVED_IN}; "
                  f"use {new} instead", DeprecationWarning, stacklevel=stacklevel)


def renamed_args(*, positional=(), renamed=None):
    """Decorator: accept deprecated positional options and renamed keywords.

    Parameters
    ----------
    positional : sequence of str
        New names of the parameters that were accepted positionally right after the
        function's positional parameters, in their old order (e.g. ``("object_mask",)``
        for ``normal_error(normals, truth, mask)``).
    renamed : dict, optional
        ``{old_keyword: new_keyword}``.

    A call in the new form runs the function directly. A call in an old form is
    rewritten to the new one and emits a single :class:`DeprecationWarning`; giving a
    value both ways (``mask=m, object_mask=m``) is a ``TypeError``, as Python does for
    duplicated arguments.
    """
    positional = tuple(positional)
    renamed = dict(renamed or {})

    def decorate(func):
        params = inspect.signature(func).parameters
        n_pos = sum(p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD)
                    for p in params.values())
        unknown = [n for n in (*positional, *renamed.values()) if n not in params]
        if unknown:
            raise TypeError(f"{func.__qualname__} has no parameter(s) {unknown}")
        name = func.__qualname__

        @functools.wraps(func)
        def wrapper(*args, **kwargs):
            if len(args) <= n_pos and not (renamed and renamed.keys() & kwargs.keys()):
                return func(*args, **kwargs)
            what, fix = [], []
            if len(args) > n_pos:
                extra = args[n_pos:]
                if len(extra) > len(positional):
                    raise TypeError(f"{name}() takes at most {n_pos + len(positional)} "
                                    f"positional arguments ({len(args)} given)")
                keys = positional[:len(extra)]
                for key, value in zip(keys, extra):
                    if key in kwargs:
                        raise TypeError(f"{name}() got multiple values for argument {key!r}")
                    kwargs[key] = value
                args = args[:n_pos]
                what.append(f"passing {', '.join(keys)} positionally")
                fix.append(", ".join(f"{k}=..." for k in keys))
            for was, now in renamed.items():
                if was in kwargs:
                    if now in kwargs:
                        raise TypeError(f"{name}() got both {was}= (deprecated) and {now}=")
                    kwargs[now] = kwargs.pop(was)
                    what.append(f"the keyword {was}=")
                    fix.append(f"{now}=...")
            warn_renamed(f"{name}(): {' and '.join(what)}", ", ".join(fix))
            return func(*args, **kwargs)

        wrapper.__wrapped__ = func
        return wrapper

    return decorate
