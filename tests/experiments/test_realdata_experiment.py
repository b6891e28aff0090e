"""The realdata experiment: folder discovery, the reduced ci copies, labels, verdicts."""
from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import psbench as ps
from psbench.experiments import realdata as R
from psbench.harness.grid import expand, load
from psbench.io import read_dataset, write_dataset


def _folder(path, size=16, k=6):
    surf = ps.make_surface("semisphere", size=size)
    lay = ps.layout(f"30x{k}")
    images = ps.render(surf, lay, model="lambert", shadows="self").images
    write_dataset(path, images, lay, object_mask=surf.object_mask, normals=surf.normals)
    return surf


def test_folders_lists_dataset_subfolders_sorted(tmp_path):
    _folder(tmp_path / "b")
    _folder(tmp_path / "a")
    (tmp_path / "not_a_dataset").mkdir()
    assert R.folders(tmp_path) == [str(tmp_path / "a"), str(tmp_path / "b")]
    assert R.folders(tmp_path / "a") == [str(tmp_path / "a")]          # a dataset itself
    assert R.folders(tmp_path / "missing") == [str(tmp_path / "missing")]   # runs fail, named
    assert R.ci_folders(tmp_path, "/x") == ["/x/a", "/x/b"]


def test_reduced_copy_is_a_block_mean(tmp_path):
    surf = _folder(tmp_path / "src", size=16)
    R._reduce(tmp_path / "src", tmp_path / "dst", 4)
    src, dst = read_dataset(tmp_path / "src"), read_dataset(tmp_path / "dst")
    assert dst.images.shape == (6, 4, 4)
    np.testing.assert_allclose(dst.images[0, 1, 2], src.images[0, 4:8, 8:12].mean(), atol=2e-4)
    assert dst.object_mask.sum() <= surf.object_mask.sum() / 16
    np.testing.assert_allclose(np.linalg.norm(dst.normals[dst.object_mask], axis=-1), 1, atol=1e-5)


def test_grid_all_lights_is_kept_against_the_command_line_default(tmp_path, monkeypatch):
    _folder(tmp_path / "obj")
    monkeypatch.setenv("PSBENCH_REALDATA", str(tmp_path))
    runs = expand(load("realdata"), "full", base={"lights": "45x8", "zenith": 45, "count": 8})
    assert {r["lights"] for r in runs} == {None, "30x8+60x8", "45x4"}
    assert {r["data"] for r in runs} == {str(tmp_path / "obj")}
    ci = expand(load("realdata", results_dir=str(tmp_path / "res")), "ci")
    assert {r["data"] for r in ci} == {str(tmp_path / "res" / "realdata_ci" / "obj")}
    R.prepare(tmp_path / "res", "ci")
    assert read_dataset(tmp_path / "res" / "realdata_ci" / "obj").images.shape == (6, 4, 4)


@pytest.mark.parametrize("r, want", [
    ({"method": "ps", "mask": "None"}, "None"),
    ({"method": "ps", "mask": "Th", "th_scope": "robust"}, "Th[robust]"),
    ({"method": "ps", "mask": "Th", "thresholds": '{"th_keep": 0.5}'}, "Th[keep=0.5]"),
    ({"method": "cauchy", "mask": "None"}, "cauchy"),
    ({"method": "l1", "mask": "Sh", "th_scope": "image"}, "l1[Sh]"),
])
def test_labels(r, want):
    assert R.label(r) == want


def test_published_l2_sits_on_the_least_squares_row():
    # the published L2 value is shown beside psbench's own least-squares row
    assert R.label({"method": "ps", "mask": "None"}) in R.THESIS["NE all"]
    assert R.THESIS["NE all"][R.label({"method": "ps", "mask": "None"})] == R.PUBLISHED["L2"]


def _rows():
    recs = []
    for obj, ne in (("cat", {"ps": 8.4, "robust": 5.9, "tsfit": 5.7, "trim": 6.5, "Th": 7.5}),
                    ("bear", {"ps": 8.4, "robust": 5.6, "tsfit": 5.5, "trim": 6.3, "Th": 5.9})):
        for lab, v in ne.items():
            meth, mask = ("ps", lab) if lab == "Th" else (lab, "None")
            for lights in (None, "30x8+60x8"):
                recs.append(dict(data=f"/d/{obj}", lights=lights, method=meth, mask=mask,
                                 th_scope="image", thresholds="{}", ne_mean=v, t_solve=0.1))
    return pd.DataFrame(recs)


def test_aggregate_and_verdicts():
    agg = R.aggregate(_rows())
    assert set(agg["part"]) == {"NE all", "NE 30x8+60x8", "time all", "time 30x8+60x8"}
    v = {x.claim: x for x in R.verdicts(agg)}
    assert v["robust beats every thesis mask on cat (all lights)"].status == "SUPPORTED"
    assert v["robust beats the published ST14 on cat and bear (all lights)"].status == "SUPPORTED"
    assert v["robust is the most accurate robust solver on cat (all lights)"].status == "SUPPORTED"
    assert all(x.status == "INCONCLUSIVE" for x in R.verdicts(R.aggregate(pd.DataFrame())))


def _with_maps(rows, skip=()):
    """The rows with an ne_map each: a disc whose error is the row's mean NE."""
    from psbench.harness import nemap

    yy, xx = np.mgrid[:40, :30]
    disc = (yy - 20) ** 2 + (xx - 15) ** 2 < 12 ** 2
    rows = rows.copy()
    rows["ne_map"] = [None if R.label(r) in skip else
                      nemap.encode(np.full(disc.shape, r["ne_mean"], np.float32), disc)
                      for r in rows.to_dict("records")]
    return rows


def test_error_maps_per_object_sorted_and_cropped():
    maps = R.error_maps(_with_maps(_rows(), skip=("trim",)), "all")
    assert set(maps) == {"cat", "bear"}
    labs = [lab for lab, _, _ in maps["cat"]]
    assert labs == ["tsfit", "robust", "Th", "None"]                # by NE; trim has no map
    for lab, ne, m in maps["cat"]:
        assert m.shape == (25, 25)                                  # the disc's box + 1 px
        assert np.isnan(m[0, 0]) and np.nanmax(m) == pytest.approx(ne, abs=0.006)
    assert R.error_maps(_rows(), "all") == {}                       # older rows: no maps
    assert R.error_maps(None) == {}


def test_figures_draw_a_map_grid_per_object_and_light_set():
    import matplotlib.pyplot as plt

    from psbench.report.figures import figures as dispatch

    rows = _with_maps(_rows())
    agg = R.aggregate(rows)
    figs = dict(R.figures(agg, rows=rows))
    stems = {"realdata_maps_cat_all", "realdata_maps_bear_all",
             "realdata_maps_cat_30x8_60x8", "realdata_maps_bear_30x8_60x8"}
    assert stems <= set(figs)
    fig = figs["realdata_maps_cat_all"]
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert titles[0] == "tsfit  5.70°" and len(titles) == 5
    bar = [ax for ax in fig.axes if ax.get_ylabel() == "angular error (deg)"]
    assert len(bar) == 1 and bar[0].get_ylim() == (0.0, 20.0)
    assert not stems & {s for s, _ in R.figures(agg)}               # no rows: bars only
    assert not stems & {s for s, _ in R.figures(agg, rows=_rows())}
    got, errs = dispatch("realdata", agg, rows=rows)                # the report passes rows
    assert not errs and stems <= {s for s, _ in got}
    plt.close("all")


def test_report_passes_rows_only_to_figures_that_take_them():
    from psbench.report.figures import _takes_rows

    assert _takes_rows(R.figures) and _takes_rows(lambda agg, **kw: None)
    assert not _takes_rows(lambda agg: None)
