"""Tests for psbench.analysis (Chapter 4 / Section 5.7 data frames), run small."""
import numpy as np
import pytest

from psbench import analysis as A
from psbench._shared.checks import PsbenchError

SIZE = 48


def test_propose_zeniths_rule_of_thumb():
    assert A.propose_zeniths() == (30.0, 60.0)
    z1, z2 = A.propose_zeniths(std_h=10, z_opt=45)
    assert np.isclose(z1 / 2 + 10, 90 - z2) and np.isclose((z1 + z2) / 2, 45)
    with pytest.raises(PsbenchError):
        A.propose_zeniths(std_h=60)


def test_ie_decomposition_parts_add_up_and_follow_fig_4_6():
    df = A.ie_decomposition("sombrero3", zeniths=(30, 60), size=SIZE)
    assert set(df["part"]) == {"highlight", "self_shadow", "cast_shadow", "total"}
    for z, g in df.groupby("source_zenith"):
        v = g.set_index("part")["ie"]
        assert np.isclose(v["total"], v["highlight"] + v["self_shadow"] + v["cast_shadow"])
    v30 = df[df.source_zenith == 30].set_index("part")["ie"]
    v60 = df[df.source_zenith == 60].set_index("part")["ie"]
    assert v30["highlight"] > v60["highlight"]            # low sources: highlights
    assert v60["self_shadow"] + v60["cast_shadow"] > v30["self_shadow"] + v30["cast_shadow"]


def test_ie_decomposition_by_surface_zenith():
    df = A.ie_decomposition("sombrero2", zeniths=(60,), size=SIZE, by="surface")
    tot = df[df.part == "total"]
    from psbench.surfaces import make_surface
    assert tot["pixels"].sum() == make_surface("sombrero2", size=SIZE).object_mask.sum()
    # with 60-degree sources shadows start beyond Z_surface = 90 - 60 = 30 (Fig. 4.10)
    sh = df[df.part == "self_shadow"].dropna(subset=["ie"])
    assert (sh[sh.hi <= 30]["ie"] == 0).all()


def test_ne_vs_surface_zenith_frame():
    df = A.ne_vs_surface_zenith("sombrero2", ("30x8", "60x8"), size=SIZE)
    assert list(df.columns[:3]) == ["surface", "lights", "source_zenith"]
    assert set(df["lights"]) == {"30x8", "60x8"}
    assert (df.groupby("lights")["count"].sum() > 0).all()


def test_ne_vs_image_count_and_source_zenith():
    df = A.ne_vs_image_count("sombrero2", counts=(4, 8), size=SIZE)
    assert len(df) == 4
    di = df[df.kind == "Di"].set_index("count")["ne"]
    hs = df[df.kind == "Hi-Sh"].set_index("count")["ne"]
    assert (di < hs).all()
    df2 = A.ne_vs_source_zenith("sombrero1", zeniths=(30, 60), counts=(8,), size=SIZE)
    assert len(df2) == 4 and set(df2["zenith"]) == {30.0, 60.0}
    again = A.ne_vs_source_zenith("sombrero1", zeniths=(30, 60), counts=(8,), size=SIZE)
    assert np.array_equal(df2["ne"].to_numpy(), again["ne"].to_numpy())  # seeded


def test_wps_table_and_pivots():
    df = A.wps_table(("sombrero1", "sombrero3"), counts=(8, 12), size=SIZE, oracle=True)
    # per surface and count: 1Z + 2Z None + 5 weights... (4 WPS weights + oracle) x 2
    assert len(df) == 2 * 2 * (1 + 1 + 5 * 2)
    ne, imp = A.table_5_5(df)
    assert ne.loc[("1Z", "None")].shape == (2,)
    base = df[df.source == "1Z"].groupby("count")["ne"].mean()
    got = df[(df.weight == "e") & ~df.binary].groupby("count")["ne"].mean()
    assert np.allclose(imp.loc[("2Z", "e")], 100 * (base - got) / base)
    # the oracle is the limit of every weighting
    for (s, n), g in df[df.source == "2Z"].groupby(["surface", "count"]):
        orc = g[g.weight == "oracle"]["ne"].min()
        fused = g[~g.weight.isin(["oracle", "None"])]  # 2Z plain PS is not a ring fusion
        assert (fused["ne"] >= orc - 1e-6).all()
    t6 = A.table_5_6(df, count=12)
    assert list(t6.index) == ["Weighted", "Binary"] and "Mean" in t6.columns


def test_wps_table_bad_counts():
    with pytest.raises(PsbenchError):
        A.wps_table(("sombrero1",), counts=(7,), size=SIZE)
    with pytest.raises(PsbenchError):
        A.wps_table(("sombrero1",), counts=(8,), weights=("bogus",), size=SIZE)


def test_mask_scores_scores_every_case_under_every_truth():
    import psbench as ps
    from psbench.analysis import TRUTHS, highlight_truth_options, mask_scores

    df = mask_scores("sombrero2", "45x8", cases=[{"mask": "None"}, {"mask": "Th"},
                                               {"mask": "Hi", "thresholds": {"k_Hi": 0.05}}],
                     th_scopes=("object",), size=48, noise=0.1, seed=1)
    assert len(df) == 4 * len(TRUTHS)              # Th also solved with th_scope=object
    assert set(df[df["th_scope"] == "object"]["mask"]) == {"Th"}
    # the default truth's QF is the one of the scene rendered with the defaults
    surf = ps.make_surface("sombrero2", size=48)
    sc = ps.render(surf, "45x8", noise=0.1, seed=1)
    res = ps.solve(sc.images, "45x8", mask="Th", object_mask=surf.object_mask, seed=1)
    qf = ps.quality_factor(~res.valid, sc, object_mask=surf.object_mask)
    row = df[(df["mask"] == "Th") & (df["th_scope"] == "image") & (df["truth"] == "cone12")]
    assert row["qf_hi"].iloc[0] == pytest.approx(qf["hi"])
    th = df[(df["mask"] == "Th") & (df["th_scope"] == "image")].set_index("truth")
    assert th["ne_mean"].nunique() == 1 and th["qf_hi"].nunique() == len(TRUTHS)
    assert highlight_truth_options("range0.5") == {"highlight": "range",
                                                   "highlight_fraction": 0.5}
    with pytest.raises(ps.PsbenchError, match="highlight truth 'peak'"):
        mask_scores("sombrero2", "45x8", truths=["peak"], size=32)
    with pytest.raises(ps.PsbenchError, match="render_options must not set"):
        mask_scores("sombrero2", "45x8", size=32, render_options={"noise": 0.1})


def test_diffuse_counts_fig_5_8():
    df = A.diffuse_counts("sombrero2", ("45x4",), size=64, truths=("cone12", "range0.1"))
    assert list(df["truth"]) == ["cone12", "range0.1"]
    d = df.set_index("truth")
    cols = [f"d{i}" for i in range(5)]
    assert np.allclose(d[cols].sum(axis=1), 1.0)
    assert d.loc["cone12", "d0"] == 0 and d.loc["cone12", "d1"] == 0      # Fig. 5.8 holds
    assert d.loc["range0.1", "d0"] + d.loc["range0.1", "d1"] > 0.2       # the old truth: not
    assert d.loc["range0.1", "highlight"] > d.loc["cone12", "highlight"] > 0
