"""Metal finishes and the Chapter 7 acquisition."""
import numpy as np
import pytest

from psbench import PsbenchError
from psbench.forensic import ACQUISITION, FINISH_PRESETS, Finish, acquire, make_cartridge


@pytest.fixture(scope="module")
def case():
    return make_cartridge(256, gun=1, case=1, finish="brass")


@pytest.fixture(scope="module")
def acq(case):
    return acquire(case, seed=2)


def test_chapter7_acquisition(case, acq):
    assert ACQUISITION["lights"] == "31x8+62x8"
    assert acq.images.dtype == np.uint8 and acq.images.shape == (16, 256, 256)
    assert acq.mean_level == pytest.approx(75.0, abs=1.5)
    z = acq.lights.zenith
    assert np.allclose(np.sort(np.unique(np.round(z))), [31, 62])
    low, high = z < 45, z > 45
    # the 31-degree ring is the bright one (thesis: "dark ones are 62 degrees")
    assert acq.images[low].mean() > 1.5 * acq.images[high].mean()
    # highlights mostly under 31 degrees, shadows mostly under 62 degrees
    assert acq.highlight[low].sum() > 3 * acq.highlight[high].sum()
    fp = case.regions["firing_pin"]
    assert acq.shadow[high][:, fp].mean() > acq.shadow[low][:, fp].mean()
    assert 0 <= acq.saturated < 0.05


def test_deterministic_and_finishes(case, acq):
    again = acquire(case, seed=2)
    assert np.array_equal(again.images, acq.images)
    nickel = acquire(case, finish="nickel", seed=2)
    assert nickel.finish is FINISH_PRESETS["nickel"]
    assert FINISH_PRESETS["nickel"].m > FINISH_PRESETS["brass"].m   # sharper lobe
    # a Lambertian finish: no highlights at all
    lam = acquire(case, finish=Finish("matte", 0.5, 0.0, 4.0), read_noise=0)
    assert not lam.highlight.any()


def test_bits_and_mean_level(case):
    a = acquire(case, bits=12, mean_level=1200.0)
    assert a.images.dtype == np.uint16 and a.mean_level == pytest.approx(1200, rel=0.02)


@pytest.mark.parametrize("kwargs, word", [
    (dict(bits=0), "bits"), (dict(bits=8.0), "bits"), (dict(mean_level=300.0), "mean_level"),
    (dict(mean_level=0), "mean_level"), (dict(read_noise=-1), "read_noise"),
    (dict(finish="gold"), "finish"),
])
def test_bad_input(case, kwargs, word):
    with pytest.raises(PsbenchError, match=word):
        acquire(case, **kwargs)
