"""Deprecation helpers: old argument forms keep working for one release, with a warning.

psbench's public functions take their arrays positionally and every option by keyword,
and the object region is ``object_mask`` everywhere (``mask`` names the mask expression
of :func:`psbench.solve` only). :func:`renamed_args` keeps the earlier call forms
working behind a :class:`DeprecationWarning` that points at the caller's line:

* options that used to be accepted positionally (``normal_error(n, t, m)``);
* keyword arguments that were renamed (``integrate(n, mask=m)``).

The result is the same as with the new form; only the warning differs.
:func:`moved_modules` does the same for public modules that moved: the old import path
gives the module at its new place, with the warning.
"""
from __future__ import annotations

import functools
import importlib
import importlib.abc
import importlib.util
import inspect
import sys
import warnings

__all__ = ["renamed_args", "warn_renamed", "renamed_names", "moved_modules", "MOVED"]

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


def renamed_names(namespace, renamed):
    """A module ``__getattr__`` for renamed module-level names.

    ``namespace`` is the module's ``globals()``, ``renamed`` ``{old: new}``: the old
    name gives the new name's value with a :class:`DeprecationWarning`. Use as
    ``__getattr__ = renamed_names(globals(), {"METHODS": "RECIPES"})``.
    """
    module = namespace["__name__"]

    def __getattr__(name):
        if name in renamed:
            warn_renamed(f"{module}.{name}", f"{module}.{renamed[name]}")
            return namespace[renamed[name]]
        raise AttributeError(f"module {module!r} has no attribute {name!r}")

    return __getattr__


#: public module paths that moved -> where they are now (the old paths go in REMOVED_IN)
MOVED = {
    "psbench.shadowmap": "psbench.render.shadowmap",
    "psbench.solve.wps": "psbench.solve.methods.wps",
    "psbench.report.html": "psbench.io.html",
    "psbench.surfaces.cartridge": "psbench.forensic.surface",
    **{f"psbench.solve.methods.{name}": f"psbench.solve.methods.robust.{name}"
       for name in ("trim", "l1", "sbl", "rpca", "huber", "cauchy", "tukey")},
}


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Imports a moved module's old path as the module itself (one object under two
    names, so a patch through either name is seen by both)."""

    def __init__(self, table):
        self.table = dict(table)

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in self.table:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        return None

    def exec_module(self, module):
        name = module.__name__
        new = self.table[name]
        # warnings skips the import machinery's frames: level 3 is the importing line
        warn_renamed(f"the module {name}", new, stacklevel=3)
        # the module left in sys.modules is the one the import statement binds
        sys.modules[name] = importlib.import_module(new)


def moved_modules(table=None):
    """Let the old import paths of moved modules (``MOVED`` by default) keep working
    behind a :class:`DeprecationWarning`; installing twice is harmless."""
    table = MOVED if table is None else table
    for finder in sys.meta_path:
        if isinstance(finder, _MovedFinder):
            finder.table.update(table)
            return
    sys.meta_path.append(_MovedFinder(table))
