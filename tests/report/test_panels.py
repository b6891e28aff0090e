"""Image panels: colour conventions and a tiny end-to-end build."""
from __future__ import annotations

import numpy as np

from psbench.report import panels


def test_encode_normals_thesis_convention():
    n = np.array([[[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]], dtype=np.float32)
    rgb = panels.encode_normals(n)
    assert np.allclose(rgb[0, 0], [0.5, 0.5, 1.0])
    assert np.allclose(rgb[0, 1], [1.0, 0.5, 0.0])
    assert np.allclose(rgb[0, 2], [0.5, 0.0, 0.0])
    masked = panels.encode_normals(n, object_mask=np.array([[True, False, True]]))
    assert np.allclose(masked[0, 1], 0)


def test_overlay_colours_tp_fp_fn():
    img = np.linspace(0, 1, 4, dtype=np.float32).reshape(1, 4)
    flagged = np.array([[True, True, False, False]])
    truth = np.array([[True, False, True, False]])
    rgb = panels.overlay(img, flagged, truth)
    assert tuple(rgb[0, 0]) == (0, 0.85, 0)        # TP green
    assert tuple(rgb[0, 1]) == (0.1, 0.3, 1.0)     # FP blue
    assert tuple(rgb[0, 2]) == (1.0, 0.1, 0.1)     # FN red
    assert rgb[0, 3, 0] == rgb[0, 3, 1] == rgb[0, 3, 2]   # untouched: grey


def test_build_panels_small(small_panels):
    folder, names = small_panels                 # panels.build_panels(folder, size=24)
    for n in ("masks.png", "ne_maps.png", "normals.png", "wps.png", "height3d.png"):
        assert n in names
        data = (folder / "panels" / n).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 1000
    page = (folder / "panels.md").read_text()
    assert "not read from the results store" in page and "mean NE" in page
