"""The ``render`` run parameter: render options (materials, departures) of a run."""
import numpy as np
import pytest

import psbench as ps
from psbench._shared.checks import PsbenchError
from psbench.harness.params import normalize, run_id, scene_key
from psbench.harness.run import _Scene


def test_default_keeps_run_ids():
    assert run_id(normalize({})) == run_id(normalize({"render": {}}))
    a, b = normalize({"render": {"gamma": 2.2}}), normalize({})
    assert run_id(a) != run_id(b) and scene_key(a) != scene_key(b)


@pytest.mark.parametrize("bad,match", [({"gama": 2}, "unknown option"),
                                       ({"gamma": 0}, "gamma"),
                                       ({"second_material": {"m": -1}}, "second_material.m"),
                                       ({"roughness": "x"}, "roughness"),
                                       ("gamma", "mapping")])
def test_bad_render_options(bad, match):
    with pytest.raises(PsbenchError, match=match) as exc:
        normalize({"render": bad})
    assert "\n" not in str(exc.value)


def test_run_renders_with_the_options_and_solves_with_nominal_lights():
    opts = {"light_error": 2.0, "gamma": 2.2, "second_material": {"rho_s": 0.2}}
    p = normalize({"surface": "sombrero", "size": 24, "lights": "30x4+60x4", "noise": 0.01,
                   "model": "ggx", "render": opts})
    sc = _Scene(p)
    surf = ps.make_surface("sombrero", size=24)
    want = ps.render(surf, "30x4+60x4", model="ggx", noise=0.01, seed=0, **opts)
    np.testing.assert_array_equal(sc.images, want.images)
    np.testing.assert_array_equal(sc.lights.directions, ps.layout("30x4+60x4").directions)
