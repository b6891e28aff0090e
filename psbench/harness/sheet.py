"""The comparison sheet of a sweep: one PNG and one HTML page.

One column per run (a method, a mask, ... whatever the sweep varies), rows input |
ground truth | normals | NE map, each picture cropped to the object and scaled to one
tile size; the NE maps share the fixed colour range (colour bar on the right). Rows a
run cannot fill (no ground truth in a real data folder) show a grey cell saying so. The
HTML page holds the summary table (best first), the sheet and, per run, links to every
picture and file it wrote. Built from the run folders alone (their ``run.json`` and
PNGs), so :func:`build_sheet` also works on folders written earlier.
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .outputs import read_run_info

__all__ = ["build_sheet", "ROWS"]

#: (file, row label) of the sheet's rows, top to bottom
ROWS = (("input.png", "input"), ("truth.png", "ground truth"), ("normals.png", "normals"),
        ("ne_map.png", "NE map"))
TILE = (200, 320)   # px: longer side of a tile, smallest and largest (few columns: larger)
PER_BAND = 6        # columns per band; more runs wrap into further bands


def _load(path):
    from ..io._common import cv2

    img = cv2().imread(str(path), cv2().IMREAD_COLOR)
    return None if img is None else np.ascontiguousarray(img[..., ::-1])


def _tile(img, box, size):
    """Crop to ``box`` and fit into ``size`` x ``size``, padded with the picture's own
    background (its corner colour: black for normal maps, white for NE maps)."""
    from ..io._common import cv2
    from ..io._pictures import _canvas

    a = img[box]
    h, w = a.shape[:2]
    s = size / max(h, w)
    nh, nw = max(1, round(h * s)), max(1, round(w * s))
    a = cv2().resize(a, (nw, nh), interpolation=cv2().INTER_AREA if s < 1 else cv2().INTER_LINEAR)
    out = _canvas(size, size, tuple(int(v) for v in a[0, 0]))
    y, x = (size - nh) // 2, (size - nw) // 2
    out[y:y + nh, x:x + nw] = a
    return out


def _missing(size, text):
    from ..io._pictures import _canvas, _draw

    return _draw(_canvas(size, size, (225, 225, 225)), [(size / 2, size / 2, text, 15, "mm")])


def _label(row, axes):
    """Column heading: the swept parameters and the mean NE."""
    def v(x):
        return Path(x).name if isinstance(x, str) and x.startswith("/") else x
    lines = [f"{a}={v(row.get(a))}" for a in axes if row.get(a) is not None]
    ne = row.get("ne_mean")
    ok = row.get("status") == "ok"
    if not ok:
        lines.append("FAILED")
    elif ne is not None and ne == ne:
        lines.append(f"NE {ne:.2f}°")
    else:
        lines.append("NE - (no truth)")
    return "\n".join(str(s) for s in lines)


def _sheet_png(cols, axes, size=None):
    """The sheet picture: ``cols`` = [(row dict, run folder)]."""
    from ..io import _pictures as P

    if size is None:       # about 1000 px of tiles per band
        size = int(np.clip(1000 // min(len(cols), PER_BAND), *TILE))
    have = {f: any((d / f).is_file() for _, d in cols) for f, _ in ROWS}
    rows = [(f, lab) for f, lab in ROWS if have[f] or f == "input.png"]
    bands = []
    gap = 6
    lab_w = max(P.text_size(lab, 16)[0] for _, lab in rows) + 16
    for b0 in range(0, len(cols), PER_BAND):
        part = cols[b0:b0 + PER_BAND]
        heads = [_label(r, axes) for r, _ in part]
        head_h = max(P.text_size(h, 15)[1] for h in heads) + 14
        grid = P._canvas(head_h + len(rows) * (size + gap), lab_w + len(part) * (size + gap))
        items = []
        for j, (r, d) in enumerate(part):
            x = lab_w + j * (size + gap)
            items.append((x + size / 2, 6, heads[j], 15, "ma"))
            m = _load(d / "object_mask.png")
            box = P.object_box(m[..., 0] > 0) if m is not None else (slice(None), slice(None))
            for i, (f, lab) in enumerate(rows):
                y = head_h + i * (size + gap)
                img = _load(d / f)
                if img is None:
                    why = "no ground truth" if f in ("truth.png", "ne_map.png") else "missing"
                    grid[y:y + size, x:x + size] = _missing(size, why)
                else:
                    grid[y:y + size, x:x + size] = _tile(img, box, size)
        for i, (_, lab) in enumerate(rows):
            items.append((8, head_h + i * (size + gap) + size / 2, lab, 16, "lm"))
        grid = P._draw(grid, items)
        if have["ne_map.png"]:
            y = head_h + [f for f, _ in rows].index("ne_map.png") * (size + gap)
            bar = P.color_bar(size, 0.0, P.NE_MAX, label="NE (deg)", over=True)
            ext = P._canvas(grid.shape[0], grid.shape[1] + bar.shape[1] + 4)
            ext[:, :grid.shape[1]] = grid
            ext[y:y + bar.shape[0], grid.shape[1] + 4:] = bar
            grid = ext
        bands.append(grid)
    width = max(b.shape[1] for b in bands)
    out = P._canvas(sum(b.shape[0] for b in bands) + 20 * (len(bands) - 1), width)
    y = 0
    for b in bands:
        out[y:y + b.shape[0], :b.shape[1]] = b
        y += b.shape[0] + 20
    return out


def build_sheet(runs, out_dir, *, axes=None, title="psbench comparison", stem="comparison"):
    """Write ``<out_dir>/<stem>.png`` and ``<stem>.html`` for ``runs``.

    Parameters
    ----------
    runs : list of (dict, Path)
        Each run's results row (as stored) and its output folder, in column order.
    out_dir : Path
    axes : list of str, optional
        Parameters named in the column headings (default: those that differ).

    Returns
    -------
    (Path, Path)
        The PNG and the HTML page.
    """
    import pandas as pd

    from ..io._pictures import write_png
    from ..io.html import Link, to_html, write_atomic
    from ._rows import rank, varying

    out_dir = Path(out_dir)
    runs = [(dict(r), Path(d)) for r, d in runs]
    if not runs:
        from .._shared.checks import PsbenchError

        raise PsbenchError("runs must hold at least one (row, folder) pair")
    axes = list(axes or varying([r for r, _ in runs]))
    png = write_png(out_dir / f"{stem}.png", _sheet_png(runs, axes))
    where = {id(r): d for r, d in runs}

    def rel(p):
        return os.path.relpath(p, out_dir)

    table = []
    for i, r in enumerate(rank([r for r, _ in runs]), 1):
        d = where[id(r)]
        info = read_run_info(d) or {}
        def f(k, r=r):
            return "-" if r.get(k) is None or r.get(k) != r.get(k) else f"{r[k]:.2f}"
        table.append({"#": str(i), **{a: str(_short(r.get(a))) for a in axes},
                      "NE mean (deg)": f("ne_mean"), "NE median (deg)": f("ne_median"),
                      "IE (% of range)": f("ie_rel"), "time (s)": f("t_total"),
                      "status": str(r.get("status")),
                      "pictures": Link(r["run_id"], rel(d) + "/"),
                      "_files": info.get("files") or []})
    files_rows = []
    for t in table:
        links = [Link(n, f"{t['pictures'].href}{n}") for n in t.pop("_files")
                 if n.endswith((".png", ".ply", ".obj", ".json"))]
        files_rows.append({"run": t["pictures"], **{a: t[a] for a in axes},
                           "files": " ".join(f"[{x.text}]({x.href})" for x in links)})
    blocks = [("h1", title),
              ("p", f"{len(runs)} runs. Columns of the sheet: one per run (the swept "
                    f"parameters: {', '.join(f'`{a}`' for a in axes)}); rows: "
                    "an input image (the light nearest the camera axis), the ground-truth "
                    "normals, the estimated normals (RGB = (n + 1) / 2) and the per-pixel "
                    "normal error (NE, angle to the true normal, 0-20 deg colour range). "
                    "Table: best first (lowest mean NE)."),
              ("table", pd.DataFrame(table), "NE: mean / median angular error over the "
                                              "object, deg; IE: L2 Lambert residual in % of "
                                              "the images' dynamic range"),
              ("img", rel(png), "comparison sheet, in the sweep's order"),
              ("p", f"[Open the sheet at full size]({rel(png)})."),
              ("h2", "Pictures and files of each run"),
              ("table", pd.DataFrame(files_rows))]
    html = write_atomic(out_dir / f"{stem}.html", to_html(blocks, title))
    return png, html


def _short(v):
    return Path(v).name if isinstance(v, str) and v.startswith("/") else v
