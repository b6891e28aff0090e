"""The picture of a congruent-matching-cells comparison (``psbench-forensic compare``).

Two panels, the band-passed reference A and compared scan B in grey (±2.5 standard
deviations of the valid heights), each with the cells drawn: on A each cell where it
lies (green: congruent, orange: not), on B where the consensus pose puts it (the inverse
of ``pose.matrix``, which maps B's pixel coordinates onto A's). Congruent cells agree
with the consensus within the translation and rotation tolerances, so their drawn place
on B is theirs to within those tolerances.
"""
from __future__ import annotations

import numpy as np

__all__ = ["cells_picture"]

GREEN = (30, 170, 60)
ORANGE = (235, 120, 20)
#: longest side of each panel (pixels)
PANEL = 560


def _gray(height, valid):
    from ..io._pictures import colorize

    v = height[valid]
    s = float(v.std()) if v.size else 1.0
    mu = float(v.mean()) if v.size else 0.0
    return colorize(height, mu - 2.5 * s, mu + 2.5 * s, cmap="gray", valid=valid)


def _filtered(topo):
    from .cmc import CMC_DEFAULTS
    from .identify import bandpass

    f = bandpass(topo.height, topo.valid, pixel_size=topo.pixel_size,
                 short=CMC_DEFAULTS["short"], long=CMC_DEFAULTS["long"])
    return np.where(topo.valid, f, np.nan)


def cells_picture(result, a, b):
    """The cells of ``result`` on the band-passed scans ``a`` and ``b``, (h, w, 3) uint8.

    Parameters
    ----------
    result : CmcResult
        ``.cells`` (DataFrame with ``top, left, height, width, congruent``), ``.pose``
        (with ``.matrix``, (2, 3) affine of B's (column, row) onto A's), ``.count``,
        ``.ccf``.
    a, b : Topography
        The two scans at one pixel size (as compared).
    """
    import cv2

    from ..io._pictures import hstack, titled

    pa, pb = _gray(_filtered(a), a.valid), _gray(_filtered(b), b.valid)
    cells = result.cells
    corners = []
    for top, left, h, w in zip(cells["top"], cells["left"], cells["height"], cells["width"]):
        l, t = left - 0.5, top - 0.5  # pixel edges, in coordinates of pixel centres
        corners.append([(l, t), (l + w, t), (l + w, t + h), (l, t + h)])
    corners = np.asarray(corners, np.float64).reshape(-1, 4, 2)
    congruent = np.asarray(cells["congruent"], bool)
    matrix = getattr(result.pose, "matrix", None)
    on_b = None
    if matrix is not None and len(corners):
        full = np.vstack([np.asarray(matrix, np.float64), [0.0, 0.0, 1.0]])
        inv = np.linalg.inv(full)[:2]
        on_b = corners @ inv[:, :2].T + inv[:, 2]
    panels = []
    for pic, pts, label in ((pa, corners, a), (pb, on_b, b)):
        scale = PANEL / max(pic.shape[:2])
        size = (max(1, round(pic.shape[1] * scale)), max(1, round(pic.shape[0] * scale)))
        img = np.ascontiguousarray(cv2.resize(pic, size, interpolation=cv2.INTER_AREA
                                              if scale < 1 else cv2.INTER_NEAREST))
        if pts is not None:
            for quad, ok in sorted(zip(pts, congruent), key=lambda t: t[1]):  # green on top
                poly = np.round((quad + 0.5) * scale - 0.5).astype(np.int32).reshape(-1, 1, 2)
                cv2.polylines(img, [poly], True, GREEN if ok else ORANGE, 3 if ok else 1,
                              cv2.LINE_AA)
        name = label.name or "scan"
        panels.append(titled(img, f"{name} ({label.pixel_size:g} um pixels)"))
    pose = result.pose
    head = (f"CMC {result.count} of {len(congruent)} cells (green: congruent, orange: not) | "
            f"CCFmax {result.ccf:.3f} | pose dx {pose.dx * a.pixel_size:+.0f} um, "
            f"dy {pose.dy * a.pixel_size:+.0f} um, theta {pose.theta:+.1f} deg")
    return titled(hstack(*panels, gap=16), head)
