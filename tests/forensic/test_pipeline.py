"""The Chapter 7 evaluation functions (small, fast versions)."""
import numpy as np
import pandas as pd
import pytest

from psbench import PsbenchError
from psbench.forensic import make_cartridge
from psbench.forensic import pipeline as P


def test_height_error_removes_offset_or_plane():
    truth = np.zeros((20, 30))
    region = np.ones((20, 30), bool)
    assert P.height_error(truth + 5.0, truth, region) == pytest.approx(0.0)
    x = np.arange(30)[None, :] + 0 * truth
    assert P.height_error(truth + 0.1 * x, truth, region, plane=True) == pytest.approx(0, abs=1e-9)
    assert P.height_error(truth + 0.1 * x, truth, region) > 0.5
    assert np.isnan(P.height_error(truth, truth, np.zeros_like(region)))


def test_auc_and_separation():
    assert P.auc([0.9, 0.8], [0.1, 0.2, 0.3]) == 1.0
    assert P.auc([0.1], [0.2]) == 0.0 and P.auc([0.5], [0.5]) == 0.5
    scores = pd.DataFrame({"region": ["r"] * 4, "method": ["m"] * 4, "integrator": ["i"] * 4,
                           "sister": [True, True, False, False],
                           "ccf": [0.7, 0.5, 0.2, 0.55]})
    row = P.separation(scores).iloc[0]
    assert row.separation == pytest.approx(0.5 - 0.55)
    assert row.auc == pytest.approx(3 / 4) and row.n_sister == 2 and row.n_non_sister == 2


def test_reconstruct_and_score_pairs():
    rec = {}
    for key in [(1, 1), (1, 2), (2, 1)]:
        rec[key] = P.reconstruct(make_cartridge(384, gun=key[0], case=key[1]),
                                 methods=("None",), integrators=("poisson",))
    r = rec[(1, 1)]
    assert len(r.rows) == 1
    row = r.rows[0]
    assert row["method"] == "None" and row["integrator"] == "poisson"
    for k in ("ne", "ne_breech_face", "ne_firing_pin", "err_firing_pin_um", "err_wall_um",
              "err_breech_face_um", "solve_s", "integrate_s"):
        assert np.isfinite(row[k]), k
    assert set(r.filtered) == {(P.TRUTH, "-", "breech_face"), ("None", "poisson", "breech_face")}
    for name in ((P.TRUTH, "-", "breech_face"), ("None", "poisson", "breech_face")):
        sc = P.score_pairs({k: v.filtered[name] for k, v in rec.items()},
                           poses={k: v.pose for k, v in rec.items()})
        assert len(sc) == 3 and sc.sister.sum() == 1
        assert sc.loc[sc.sister, "ccf"].min() > sc.loc[~sc.sister, "ccf"].max()
        assert sc.loc[sc.sister, "angle_error"].max() < 1.0     # registered correctly
        assert sc.loc[~sc.sister, "angle_error"].isna().all()
    summary = P.separation(sc.assign(region="breech_face", method="m", integrator="i"))
    assert summary.registered.iloc[0] == 1.0 and summary.auc.iloc[0] == 1.0


def test_unknown_names():
    c = make_cartridge(256, gun=1, case=1)
    with pytest.raises(PsbenchError, match="method"):
        P.reconstruct(c, methods=("bogus",))
    with pytest.raises(PsbenchError, match="integrator"):
        P.reconstruct(c, integrators=("bogus",))
    with pytest.raises(PsbenchError, match="region"):
        P.reconstruct(c, compare=("bogus",))


def test_integrators_are_warmed_once_per_process_before_timing(monkeypatch):
    # the first masked Poisson solve of a process loads compiled kernels; the warm-up
    # must run it (on the CG path: a disc larger than SMALL_COMPONENT) once, untimed
    from psbench.integrate.poisson import SMALL_COMPONENT

    calls = []
    monkeypatch.setattr(P, "_WARM", set())
    monkeypatch.setitem(P.INTEGRATORS, "poisson",
                        lambda n, m: calls.append((n.shape, int(m.sum()))))
    P.warm_up_integrators(["poisson"])
    P.warm_up_integrators(["poisson"])
    assert len(calls) == 1
    shape, area = calls[0]
    assert shape[2] == 3 and area > SMALL_COMPONENT
