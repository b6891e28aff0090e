"""The procedural cartridge case: determinism, sisters, regions, bad input."""
from importlib import metadata

import numpy as np
import pytest

from psbench import PsbenchError
from psbench.forensic import Cartridge, compare, make_cartridge
from psbench.forensic.cartridge import MAX_PIXEL_SIZE
from psbench.forensic.surface import SURFACE


@pytest.fixture(scope="module")
def cases():
    return {k: make_cartridge(512, gun=k[0], case=k[1]) for k in [(3, 3), (3, 5), (4, 3), (4, 5)]}


def test_deterministic_per_gun_and_case(cases):
    again = make_cartridge(512, gun=3, case=5)
    ref = cases[(3, 5)]
    assert np.array_equal(again.height, ref.height)
    assert np.array_equal(again.normals, ref.normals)
    assert all(np.array_equal(again.regions[k], ref.regions[k]) for k in ref.regions)
    assert dict(again.pose) == dict(ref.pose)
    assert not np.array_equal(cases[(3, 3)].height, ref.height)     # another case
    assert not np.array_equal(cases[(4, 5)].height, ref.height)     # another gun


def test_units_and_geometry(cases):
    c = cases[(3, 3)]
    assert isinstance(c, Cartridge) and c.shape == (512, 512)
    assert c.pixel_size == pytest.approx(4.9 * 2048 / 512)
    np.testing.assert_allclose(c.height_um, c.height * c.pixel_size, rtol=1e-6)
    assert np.array_equal(c.object_mask, c.object_mask) and np.array_equal(c.regions["case"], c.object_mask)
    r = c.regions
    assert not (r["breech_face"] & r["firing_pin"]).any()
    assert (r["firing_pin"] & ~r["primer"]).sum() == 0
    assert (r["firing_pin_wall"] <= r["firing_pin"]).all()
    assert r["headstamp"].sum() > 0 and r["ejector"].sum() > 0 and r["bevel"].sum() > 0
    # the firing pin is a crater 140-240 µm (x depth scale) below the primer face
    depth = np.median(c.height_um[r["breech_face"]]) - c.height_um[r["firing_pin"]].min()
    assert 100 < depth < 300
    # its walls are steep, the breech face nearly flat
    assert np.percentile(c.zenith[r["firing_pin_wall"]], 90) > 45
    assert np.median(c.zenith[r["breech_face"]]) < 10


def test_sisters_share_breech_face_marks(cases):
    def ccf(a, b):
        A, B = cases[a], cases[b]
        return compare(A.height_um, B.height_um, A.regions["breech_face"],
                       B.regions["breech_face"], pixel_size=A.pixel_size).ccf

    sisters = [ccf((3, 3), (3, 5)), ccf((4, 3), (4, 5))]
    others = [ccf((3, 3), (4, 3)), ccf((3, 5), (4, 5)), ccf((3, 3), (4, 5))]
    assert min(sisters) > 0.25, sisters
    assert max(others) < 0.15, others


def test_any_size_and_pixel_size():
    c = make_cartridge(300, gun=1, case=2, pixel_size=35.0, finish="nickel")
    assert c.shape == (300, 300) and c.pixel_size == 35.0 and c.finish == "nickel"


@pytest.mark.parametrize("kwargs, word", [
    (dict(size=512, pixel_size=0), "pixel_size"),
    (dict(size=512, pixel_size=-4.9), "pixel_size"),
    (dict(size=512, pixel_size="big"), "pixel_size"),
    (dict(size=512, gun=3.0), "gun"),
    (dict(size=512, gun="3"), "gun"),
    (dict(size=512, case=True), "case"),
    (dict(size=512, case=-1), "case"),
    (dict(size=128), "too coarse"),
    (dict(size=256, pixel_size=10.0), "cannot hold"),
    (dict(size=512, finish="gold"), "finish"),
    (dict(size=512.0), "size"),
])
def test_bad_input(kwargs, word):
    with pytest.raises(PsbenchError, match=word) as err:
        make_cartridge(**kwargs)
    assert "\n" not in str(err.value)


def test_max_pixel_size_is_the_limit():
    make_cartridge(256, gun=1, case=0, pixel_size=MAX_PIXEL_SIZE)
    with pytest.raises(PsbenchError, match="too coarse"):
        make_cartridge(256, gun=1, case=0, pixel_size=MAX_PIXEL_SIZE * 1.01)


def test_surface_spec_and_entry_point():
    assert SURFACE.name == "cartridge"
    c = SURFACE.func(size=256, gun=2, case=1)
    assert isinstance(c, Cartridge) and c.gun == 2 and c.case == 1
    assert c.shape == (256, 256)
    eps = {ep.name: ep.value for ep in metadata.entry_points(group="psbench.surfaces")}
    if "cartridge" not in eps:
        pytest.skip("psbench is not installed with its entry points")
    assert eps["cartridge"] == "psbench.forensic.surface:SURFACE"
