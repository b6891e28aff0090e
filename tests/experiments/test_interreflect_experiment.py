"""The interreflection experiment: grid, aggregate and verdicts (no solving)."""
import pandas as pd

from psbench import registry
from psbench.harness.grid import expand
from psbench.report.verdicts import INCONCLUSIVE, NOT_SUPPORTED, SUPPORTED


def _exp():
    return registry.get("experiments", "interreflection")


def test_grid_at_ci_scale():
    runs = expand("interreflection", scale="ci")
    assert len(runs) == 3 * 2 * 2 * 7
    assert {r["bounces"] for r in runs} == {None, 1}
    assert {r["size"] for r in runs} == {48, None}  # None: the firing-pin height file
    assert {str(r["surface"]).endswith("firing_pin.npy") for r in runs} == {True, False}


def _rows():
    recs = []
    ne = {"None": 8.0, "SR": 1.0, "robust": 5.0, "trim": 5.5, "Th-Hi-Re-Sh": 20.0,
          "Th-Hi-Re-Sh-SR": 3.0}
    for surf in ("cup", "vgroove"):
        for model in ("lambert", "ts"):
            for b in (None, 1):
                for solver, v in ne.items():
                    method = solver if solver in ("robust", "trim") else "ps"
                    mask = "None" if method != "ps" else solver
                    recs.append(dict(surface=surf, model=model, bounces=b, mask=mask,
                                     method=method, weighted=False,
                                     ne_mean=v if b else 2.0, qf_sr=0.9 if b else None,
                                     t_solve=0.1))
    return pd.DataFrame(recs)


def test_aggregate_and_verdicts():
    mod = _exp()
    agg = mod.aggregate(_rows())
    assert set(agg["part"]) == {"ne lambert", "ne ts", "qf_sr", "time"}
    cell = agg[(agg["part"] == "ne lambert") & (agg["row"] == "SR") & (agg["column"] == "cup 1")]
    assert float(cell["value"].iloc[0]) == 1.0
    out = {v.claim: v.status for v in mod.verdicts(agg, None)}
    first = next(iter(out))
    assert out[first] == SUPPORTED
    assert "robust" in " ".join(out) and any(s == INCONCLUSIVE for s in out.values())
    assert all(s in (SUPPORTED, NOT_SUPPORTED, INCONCLUSIVE) for s in out.values())


def test_verdicts_on_empty_aggregate():
    mod = _exp()
    agg = mod.aggregate(_rows().iloc[:0])
    assert all(v.status == INCONCLUSIVE for v in mod.verdicts(agg, None))
