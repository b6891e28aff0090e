"""The run spec: one declaration per parameter drives Hydra's defaults, the store's
columns, normalization / validation and ``psbench --help``; method options from the
command line; ``--help`` and ``--version`` in-process."""
import dataclasses
import json
import sys

import pyarrow as pa
import pytest

import psbench
from psbench import PsbenchError, registry
from psbench.harness import app, choices, params, run, schema, spec
from psbench.registry import Mask, Method
from psbench.solve.base import Options, check_number

# ids computed by psbench before the run spec existed: stored runs must keep them
OLD_IDS = [({}, "8b719489c90b154c"),
           ({"mask": "Th-Hi-Re-Sh", "weighted": True}, "eeacf4f43eb5ca75"),
           ({"zenith": 30, "count": 8}, "9eed601aa14c5279"),
           ({"method": "wps", "weight": "eZsource", "lights": "30x8+60x8"}, "67a2420e78c0d3d4"),
           ({"kind": "cond", "lights": "45x8"}, "10bf93263576b5f9")]


@pytest.mark.parametrize("given, rid", OLD_IDS)
def test_run_ids_of_stored_runs_unchanged(given, rid):
    assert params.run_id(params.normalize(given)) == rid
    # empty options, or options equal to the defaults, are the same run
    assert params.run_id(params.normalize({**given, "options": {}})) == rid
    if given.get("kind") != "cond":
        assert params.run_id(params.normalize({**given, "options": {"max_iter": 10}})) == rid


def test_spec_drives_schema_and_defaults():
    cols = dict(zip(schema.SCHEMA.names, schema.SCHEMA.types))
    want = {"str": pa.string(), "int": pa.int64(), "float": pa.float64(), "bool": pa.bool_(),
            "mapping": pa.string(), "list": pa.string()}
    for p in spec.PARAMS:
        assert cols[p.name] == want[p.type], p.name
    assert schema.PARAM_COLUMNS == tuple(p.name for p in spec.PARAMS) + ("n_images",)
    assert params.PARAMS == {p.name: p.default for p in spec.PARAMS if not p.alias}
    assert set(app._KEYS) | {"experiment"} == {p.name for p in spec.PARAMS + spec.SETTINGS}


def test_hydra_config_is_the_spec():
    """The config Hydra composes holds exactly the spec's keys and defaults."""
    from hydra import compose, initialize_config_module
    from omegaconf import OmegaConf

    spec.register_hydra()
    with initialize_config_module(config_module="psbench.conf", version_base="1.3"):
        cfg = compose(config_name="config", overrides=["zenith=30"])
    c = OmegaConf.to_container(cfg, resolve=True)
    names = [p.name for p in spec.PARAMS + spec.SETTINGS]
    assert list(c) == names
    for p in spec.PARAMS + spec.SETTINGS:
        if p.name not in ("lights", "zenith", "results_dir"):
            assert c[p.name] == p.default, p.name
    assert c["lights"] == "30x8"                        # ${zenith}x${count}


def test_options_normalized_and_validated():
    a = params.normalize({"mask": "Th-Hi", "options": {"max_iter": 5, "iter_tol": 0}})
    assert a["options"] == {"iter_tol": 0, "max_iter": 5}
    assert params.run_id(a) != params.run_id(params.normalize({"mask": "Th-Hi"}))
    same = params.normalize({"mask": "Th-Hi", "options": {"iter_tol": 0, "max_iter": 5,
                                                         "th_offset": False}})
    assert params.run_id(same) == params.run_id(a)       # a default value is dropped
    with pytest.raises(PsbenchError, match="unknown option.*'bogus'.*valid options: max_iter"):
        params.normalize({"options": {"bogus": 1}})
    with pytest.raises(PsbenchError, match="options: max_iter must be an integer"):
        params.normalize({"options": {"max_iter": -1}})
    with pytest.raises(PsbenchError, match="options: th_offset must be true or false"):
        params.normalize({"options": {"th_offset": "yes"}})
    with pytest.raises(PsbenchError, match="options.weighted is a run parameter"):
        params.normalize({"options": {"weighted": True}})
    with pytest.raises(PsbenchError, match="options must be a mapping"):
        params.normalize({"options": [1]})
    assert params.normalize({"kind": "cond", "options": {"max_iter": 5}})["options"] == {}


def _spy_solve(monkeypatch):
    solve_mod = sys.modules["psbench.solve"]
    real, calls = solve_mod.solve, []

    def spy(images, lights, **kw):
        calls.append(kw)
        return real(images, lights, **kw)

    monkeypatch.setattr(solve_mod, "solve", spy)
    return calls


def test_options_reach_solve_and_the_row(monkeypatch):
    import numpy as np

    from psbench.metrics import normal_error

    calls = _spy_solve(monkeypatch)
    p = params.normalize({"surface": "sombrero2", "size": 32, "mask": "Th-Hi-Re-Sh",
                          "options": {"max_iter": 1, "iter_tol": 0}})
    row = run.execute(p, sweep="x")
    assert row["status"] == "ok", row.get("traceback")
    assert calls[-1]["max_iter"] == 1 and calls[-1]["iter_tol"] == 0
    assert json.loads(row["options"]) == {"iter_tol": 0, "max_iter": 1}
    assert "max_iter=1" in run.format_row(row)
    # the stored figure is the one solve gives with those options
    surf = psbench.make_surface("sombrero2", size=32)
    sc = psbench.render(surf, psbench.layout("45x8"), model="ts", noise=0.05, seed=0)
    ref = sys.modules["psbench.solve"].solve(sc.images, psbench.layout("45x8"),
                                             mask="Th-Hi-Re-Sh", object_mask=surf.object_mask,
                                             max_iter=1, iter_tol=0)
    assert row["ne_mean"] == pytest.approx(normal_error(ref.normals, surf.normals, object_mask=surf.object_mask),
                                           rel=1e-9)
    default = run.execute(params.normalize({"surface": "sombrero2", "size": 32,
                                            "mask": "Th-Hi-Re-Sh"}), sweep="x")
    assert default["options"] is None and "max_iter" not in calls[-1]
    assert np.isfinite(default["ne_mean"])


# ---------------------------------------------------------------- a plug-in of each kind
@dataclasses.dataclass
class ToyOptions(Options):
    """Options of the toy method.

    Parameters
    ----------
    gain : float
        Factor applied to the least-squares solution; > 0.
    """

    gain: float = 1.0

    def __post_init__(self):
        super().__post_init__()
        check_number(self.gain, "gain", lo=0, lo_open=True)


def _toy(problem, options):  # pragma: no cover - solve() dispatch is not exercised here
    raise NotImplementedError


@pytest.fixture
def toy_plugins():
    mask = Mask(name="Toy", stage="image", func=lambda *a, **k: None,
                help="toy mask: keeps every observation")
    method = Method(name="toy", func=_toy, options=ToyOptions, help="toy method for tests")
    registry.register("masks", mask)
    registry.register("methods", method)
    yield
    registry.unregister("masks", "Toy")
    registry.unregister("methods", "toy")


def test_registered_method_options_checked_by_its_class(toy_plugins):
    p = params.normalize({"method": "toy", "options": {"gain": 2.5, "max_iter": 3}})
    assert p["options"] == {"gain": 2.5, "max_iter": 3}
    params.validate({**p, "mask": "Toy"})
    with pytest.raises(PsbenchError, match="gain must be a number in"):
        params.normalize({"method": "toy", "options": {"gain": -1}})
    with pytest.raises(PsbenchError, match="for method 'toy'; valid options: .*gain"):
        params.normalize({"method": "toy", "options": {"gian": 2}})
    with pytest.raises(PsbenchError, match="method='nope' is not known.*toy"):
        params.normalize({"method": "nope", "options": {"gain": 2}})


def test_cli_options_flow_in_process(toy_plugins, monkeypatch, tmp_path, capsys):
    """psbench method=toy options.gain=2: checked by ToyOptions, passed to solve, stored."""
    solve_mod = sys.modules["psbench.solve"]
    real, calls = solve_mod.solve, []

    def solve_as_ps(images, lights, **kw):        # records the call, then solves as ps
        calls.append(dict(kw))
        kw = {k: v for k, v in kw.items() if k != "gain"}
        return real(images, lights, **{**kw, "method": "ps"})

    monkeypatch.setattr(solve_mod, "solve", solve_as_ps)
    res = tmp_path / "res"
    app.main(["method=toy", "mask=None", "options.gain=2", "size=16", f"results_dir={res}"])
    out = capsys.readouterr().out
    assert "mask=None toy gain=2" in out
    assert calls[-1]["gain"] == 2 and calls[-1]["method"] == "toy"
    df = psbench.harness.read_store(res)
    assert json.loads(df.loc[0, "options"]) == {"gain": 2} and df.loc[0, "method"] == "toy"
    with pytest.raises(SystemExit) as e:
        app.main(["method=toy", "options.gain=0", "size=16", f"results_dir={res}"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "options: gain must be a number in (0, inf]" in err and "Traceback" not in err
    assert len(calls) == 1 and len(psbench.harness.read_store(res)) == 1   # refused up front


def test_help_lists_registries_options_and_figures(toy_plugins, capsys):
    assert app.main(["--help"]) is None
    out = capsys.readouterr().out
    for p in spec.PARAMS + spec.SETTINGS:
        assert f"  {p.name}=" in out, p.name
    assert "Toy" in out and "toy mask: keeps every observation" in out
    assert "toy method for tests" in out
    assert "gain=1.0" in out and "Factor applied to the least-squares solution" in out
    assert "max_iter=10" in out                       # the mask engine's options
    for group in ("surfaces", "models", "wps_weights", "experiments"):
        for name in getattr(choices, group)():
            assert name in out, (group, name)
    assert "NE  normal error" in out and "degrees" in out
    assert "IE  intensity error" in out and "L1" in out and "L2" in out and "Linf" in out
    assert "% of the" in out and "intensity units" in out
    assert "QF  quality factor of a mask, 0-1" in out
    assert "Hydra" not in out.split("\n")[0]


def test_help_while_registries_are_empty(monkeypatch, capsys):
    for name in ("masks", "methods", "surfaces", "experiments"):
        monkeypatch.setattr(registry, name, lambda: {})
    monkeypatch.setattr(choices, "_legacy", lambda ref: None)
    app.main(["-h"])
    out = capsys.readouterr().out
    assert out.count("(none registered)") >= 5 and "NE  normal error" in out


def test_version_is_psbench_s(capsys):
    app.main(["--version"])
    assert capsys.readouterr().out == f"psbench {psbench.__version__}\n"


def test_mapping_entries_need_no_plus():
    assert app._entries(["options.max_iter=5", "++options.x=1", "thresholds.k_low=0.1",
                         "args.sleep=1", "hydra.job.chdir=false", "mask=Th"]) == \
        ["++options.max_iter=5", "++options.x=1", "++thresholds.k_low=0.1", "++args.sleep=1",
         "hydra.job.chdir=false", "mask=Th"]
