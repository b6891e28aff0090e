"""How a comparison with the thesis is shown: units, labels, precision, table layout.

A page's table puts psbench, the thesis and their difference in separate columns, each
with its unit and one precision per column (:func:`part_table`). Units and precision
come from the cell's tolerance class (the module's ``cell_kind(part, column)``, default
``ne``; see :data:`CELL_KINDS`); an experiment module may refine them with optional
presentation hooks:

``cell_unit(part, column) -> str``
    Unit of a cell (``"deg"``, ``"%"``, ``"x 2Z PS"``; ``""`` for none).
``column_label(part, column) -> str``
    Header of a column (default: :data:`COLUMN_NAMES`, else the column key).
``TABLE_AXES : dict``
    ``{part: (rows title, columns title)}``: what the rows and the columns are (key
    ``"*"``: every part).
``PART_TITLES : dict``
    ``{part: heading}`` of the page's part tables (default ``Part: <part>``).

Times are never compared with the thesis's seconds (Matlab on other hardware): a
``time`` column is shown as a ratio to the part's reference row (``None``, i.e. the
unmasked solve of the same run set) for psbench and for the thesis, beside psbench's own
seconds.
"""
from __future__ import annotations

import math

import pandas as pd

from .._shared.deprecation import renamed_names

__all__ = ["CELL_KINDS", "COLUMN_NAMES", "cell_kind", "unit", "decimals", "column_label",
           "table_axes", "part_title", "fmt", "part_table", "TIME_REFERENCE"]

#: cell kind (tolerance class, an experiment's ``cell_kind``) -> (unit, decimals);
#: "exact": as few decimals as show the value (sweep values such as thresholds, printed
#: like the thesis prints them). Formerly ``KINDS``.
CELL_KINDS = {"ne": ("deg", 2), "qf": ("", 2), "cond": ("", 4), "percent": ("%", 1),
         "ratio": ("x", 2), "ie": ("% of range", 2), "time": ("s", 4), "threshold": ("", "exact")}
COLUMN_NAMES = {"ne": "NE", "time": "time", "qf_hi": "QF highlight", "qf_sh": "QF shadow",
                "qf_total": "QF total", "mean": "mean", "overall": "overall"}
#: row a time column is divided by, when the part has it
TIME_REFERENCE = "None"
MISSING = "—"


def _module(name):
    from .tables import experiment_module

    return experiment_module(name)


def cell_kind(name, part, column) -> str:
    """Kind (tolerance class) of a cell: the experiment module's ``cell_kind(part,
    column)``, default ``ne`` (formerly ``kind``)."""
    fn = getattr(_module(name), "cell_kind", None)
    try:
        k = str(fn(part, column)) if fn is not None else "ne"
    except Exception:  # noqa: BLE001 - a presentation hook must not break the page
        k = "ne"
    return k if k in CELL_KINDS else "ne"


def unit(name, part, column) -> str:
    """Unit of a cell (module ``cell_unit`` or from its kind)."""
    fn = getattr(_module(name), "cell_unit", None)
    if fn is not None:
        try:
            return str(fn(part, column))
        except Exception:  # noqa: BLE001
            pass
    return CELL_KINDS[cell_kind(name, part, column)][0]


def decimals(name, part, column):
    """Decimals of a cell's numbers (one precision per column)."""
    return CELL_KINDS[cell_kind(name, part, column)][1]


def column_label(name, part, column) -> str:
    """Header of a column (module ``column_label`` or :data:`COLUMN_NAMES`)."""
    fn = getattr(_module(name), "column_label", None)
    if fn is not None:
        try:
            return str(fn(part, column))
        except Exception:  # noqa: BLE001
            pass
    return COLUMN_NAMES.get(str(column), str(column))


def table_axes(name, part) -> tuple[str, str]:
    """(rows title, columns title) of one part (module ``TABLE_AXES``; default ("", ""))."""
    axes = getattr(_module(name), "TABLE_AXES", None) or {}
    r, c = axes.get(part, axes.get("*", ("", "")))
    return str(r or ""), str(c or "")


def part_title(name, part) -> str:
    """Heading of one part's table (module ``PART_TITLES``; default ``Part: <part>``)."""
    titles = getattr(_module(name), "PART_TITLES", None) or {}
    return str(titles.get(part) or (f"Part: {part}" if part else "Values"))


def _ok(x) -> bool:
    return x is not None and not (isinstance(x, float) and math.isnan(x))


def fmt(x, nd, sign=False) -> str:
    """``x`` with ``nd`` decimals (``"exact"``: as few as show it, at most 3); a dash
    when missing; ``sign`` forces a leading + (differences)."""
    if not _ok(x):
        return MISSING
    x = float(x)
    if nd == "exact":
        s = f"{x:.3f}".rstrip("0").rstrip(".")
        s = "0" if s in ("-0", "") else s
        return ("+" + s if sign and not s.startswith("-") else s)
    if round(x, nd) == 0:
        x = 0.0                        # no "-0.00"
    return f"{x:+.{nd}f}" if sign else f"{x:.{nd}f}"


def _head(label, u):
    return f"{label} ({u})" if u else label


def _numeric(cols) -> bool:
    try:
        [float(c) for c in cols]
        return True
    except (TypeError, ValueError):
        return False


def _sort_cols(cols):
    try:
        return sorted(cols, key=float)
    except (TypeError, ValueError):
        return cols


def _layout(name, part, rows, cols, cell):
    """``[(column, [sub, ...])]``; non-numeric columns only the thesis has (e.g. its
    objects where psbench measured others) go last."""
    has_th = {c: any(_ok(cell.get((r, c), (None, None))[1]) for r in rows) for c in cols}
    has_ps = {c: any(_ok(cell.get((r, c), (None, None))[0]) for r in rows) for c in cols}
    out = []
    for c in cols:
        if cell_kind(name, part, c) == "time":
            ref = TIME_REFERENCE in rows
            subs = (["psbench", "psbench_ratio", "thesis_ratio"] if ref and has_th[c]
                    else ["psbench", "psbench_ratio"] if ref else ["psbench"])
        else:
            subs = (["psbench", "thesis", "diff"] if has_th[c] and has_ps[c]
                    else ["thesis"] if has_th[c] else ["psbench"])
        out.append((c, subs))
    if _numeric(cols):
        return out                                  # numeric columns keep their order
    return sorted(out, key=lambda cs: cs[1] == ["thesis"])


_SUBNAME = {"psbench": "psbench", "thesis": "thesis", "diff": "Δ",
            "psbench_ratio": f"psbench (x {TIME_REFERENCE})",
            "thesis_ratio": f"thesis (x {TIME_REFERENCE})"}


def _value(s, ps, th, nd, cell, r, c):
    if s == "psbench":
        return fmt(ps, nd)
    if s == "thesis":
        return fmt(th, nd)
    if s == "diff":
        return fmt(ps - th, nd, sign=True) if _ok(ps) and _ok(th) else MISSING
    col = 0 if s == "psbench_ratio" else 1
    v = cell.get((r, c), (None, None))[col]
    base = cell.get((TIME_REFERENCE, c), (None, None))[col]
    return fmt(v / base, 1) if _ok(v) and _ok(base) and base > 0 else MISSING


def part_table(name, cmp: pd.DataFrame, part: str, max_cols: int = 18):
    """One part of a comparison (:func:`psbench.report.tables.compare`) as a page table;
    returns ``(DataFrame, caption)``.

    Columns are two-level, ``(column header, "psbench" | "thesis" | "Δ")``: a column
    the thesis printed nothing for has psbench's values only, one psbench has no value
    for the thesis's only; a ``time`` column becomes ``psbench (s)``, ``psbench (x
    None)``, ``thesis (x None)``. Cells are formatted strings with one precision per
    column. The caption says what rows, columns and values are (the unit, when all
    columns share one; otherwise each header carries its own). A part wider than
    ``max_cols`` value columns is returned in long form (one row per cell).
    """
    p = cmp[cmp["part"] == part]
    rows = list(dict.fromkeys(p["row"]))
    cols = _sort_cols(list(dict.fromkeys(p["column"])))
    rtitle, ctitle = table_axes(name, part)
    cell = {(r, c): (ps, th) for r, c, ps, th in
            zip(p["row"], p["column"], p["psbench"], p["thesis"])}
    layout = _layout(name, part, rows, cols, cell)
    units = {unit(name, part, c) for c, _ in layout if cell_kind(name, part, c) != "time"}
    shared = units.pop() if len(units) == 1 and all(
        cell_kind(name, part, c) != "time" for c, _ in layout) else None
    cap = [f"rows: {rtitle}" if rtitle else "", f"columns: {ctitle}" if ctitle else "",
           f"values in {shared}" if shared else ""]
    caption = "; ".join(x for x in cap if x) or None
    if sum(len(s) for _, s in layout) > max_cols:
        return _long_table(name, p, part, rtitle), caption
    multi = any(subs != ["psbench"] for _, subs in layout)
    labels = [("", rtitle or "row")]
    for c, subs in layout:
        k = cell_kind(name, part, c)
        head = column_label(name, part, c) if shared is not None or k == "time" else \
            _head(column_label(name, part, c), unit(name, part, c))
        for s in subs:
            sub = f"psbench ({unit(name, part, c)})" if s == "psbench" and k == "time" \
                else _SUBNAME[s]
            labels.append((head, sub))
    recs = []
    for r in rows:
        rec = [r]
        for c, subs in layout:
            nd = decimals(name, part, c)
            ps, th = cell.get((r, c), (None, None))
            rec += [_value(s, ps, th, nd, cell, r, c) for s in subs]
        recs.append(rec)
    columns = pd.MultiIndex.from_tuples(labels) if multi else \
        [rtitle or "row"] + [lab[0] for lab in labels[1:]]
    return pd.DataFrame(recs, columns=columns), caption


def _long_table(name, p, part, rtitle) -> pd.DataFrame:
    recs = []
    for r, c, ps, th in zip(p["row"], p["column"], p["psbench"], p["thesis"]):
        nd = decimals(name, part, c)
        recs.append([r, column_label(name, part, c), unit(name, part, c), fmt(ps, nd),
                     fmt(th, nd),
                     fmt(ps - th, nd, sign=True) if _ok(ps) and _ok(th) else MISSING])
    return pd.DataFrame(recs, columns=[rtitle or "row", "column", "unit", "psbench", "thesis",
                                       "Δ"])


__getattr__ = renamed_names(globals(), {"KINDS": "CELL_KINDS", "kind": "cell_kind"})
