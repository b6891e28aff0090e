"""Band-pass, registration and CCFmax."""
import cv2
import numpy as np
import pytest

from psbench import PsbenchError
from psbench.forensic import bandpass, compare, make_cartridge, ncc, register
from psbench.forensic.identify import SHORT_CUTOFF, LONG_CUTOFF, cutoff_sigma


def test_cutoffs_and_gaussian_weighting():
    assert (SHORT_CUTOFF, LONG_CUTOFF) == (16.0, 250.0)
    # ISO 16610-61: sigma = lambda sqrt(ln 2) / (pi sqrt 2); 50 % transmission at lambda
    assert cutoff_sigma(250.0, 1.0) == pytest.approx(46.85, abs=0.01)
    lam, ps = 250.0, 2.0
    sigma_um = cutoff_sigma(lam, ps) * ps
    assert np.exp(-2 * (np.pi * sigma_um / lam) ** 2) == pytest.approx(0.5, abs=1e-9)


def test_bandpass_keeps_the_band_and_drops_form_and_noise():
    ps, n = 4.0, 512
    x = np.arange(n) * ps
    X, Y = np.meshgrid(x, x)
    mark = np.sin(2 * np.pi * X / 60.0)                      # 60 µm: inside the band
    form = 0.01 * X + 0.02 * Y + 5.0 + 3 * np.sin(2 * np.pi * Y / 3000.0)
    noise = 0.5 * np.sin(2 * np.pi * X / 8.5)                # shorter than 16 µm
    out = bandpass(mark + form + noise, pixel_size=ps)
    core = (slice(150, -150), slice(150, -150))
    assert ncc(out[core], mark[core]) > 0.97
    amp = np.sqrt(2) * out[core].std()
    assert 0.7 < amp < 1.05                                   # transmission at 60 µm


def test_bandpass_ignores_invalid_pixels():
    z = np.random.default_rng(0).normal(size=(128, 128)).astype(np.float32)
    valid = np.zeros_like(z, bool)
    valid[30:100, 30:100] = True
    z2 = np.where(valid, z, 1e6)
    a = bandpass(z, valid, pixel_size=2.0)
    b = bandpass(z2, valid, pixel_size=2.0)
    assert np.allclose(a, b, atol=1e-4) and (a[~valid] == 0).all()


@pytest.mark.parametrize("kwargs, word", [
    (dict(pixel_size=4.9, short=5.0), "short"),       # below 2 x pixel (Nyquist)
    (dict(pixel_size=4.9, long=10.0), "long"),        # not above short
    (dict(pixel_size=4.9, long=1e6), "long"),         # beyond the image
    (dict(pixel_size=0), "pixel_size"),
    (dict(pixel_size=-1), "pixel_size"),
])
def test_bad_cutoffs(kwargs, word):
    with pytest.raises(PsbenchError, match=word) as err:
        bandpass(np.zeros((64, 64)), **kwargs)
    assert "\n" not in str(err.value)


@pytest.fixture(scope="module")
def marks():
    c = make_cartridge(512, gun=2, case=1)
    v = c.regions["breech_face"]
    return bandpass(c.height_um, v, pixel_size=c.pixel_size, short=4 * c.pixel_size), v


def test_self_rotated_and_shifted_scores_one(marks):
    """Acceptance: CCFmax of a height map with itself rotated and shifted is ~1."""
    f, v = marks
    n = f.shape[0]
    M = cv2.getRotationMatrix2D(((n - 1) / 2, (n - 1) / 2), 37.3, 1.0)
    M[:, 2] += (13.4, -7.7)
    g = cv2.warpAffine(f, M, (n, n), flags=cv2.INTER_CUBIC)
    w = cv2.warpAffine(v.astype(np.float32), M, (n, n), flags=cv2.INTER_NEAREST) > 0.5
    m = register(f, g, v, w)
    assert m.ccf > 0.95
    assert min(abs(m.angle - (360 - 37.3)), abs(m.angle + 37.3)) < 0.3
    # the returned map takes g's pixels back onto f's: compose with M ~ identity
    full = np.vstack([m.matrix, [0, 0, 1]]) @ np.vstack([M, [0, 0, 1]])
    np.testing.assert_allclose(full[:2, :2], np.eye(2), atol=0.01)
    assert np.abs(full[:2, 2]).max() < 1.0
    assert m.overlap > 0.9


def test_unrelated_maps_score_low(marks):
    f, v = marks
    rng = np.random.default_rng(1)
    g = bandpass(rng.normal(size=f.shape), v, pixel_size=4 * 4.9, short=4 * 4.9 * 2)
    assert register(f, g, v, v).ccf < 0.2


def test_compare_and_bad_register_input(marks):
    f, v = marks
    with pytest.raises(PsbenchError, match="min_overlap"):
        register(f, f, v, v, min_overlap=0)
    with pytest.raises(PsbenchError, match="valid"):
        register(f, f, np.zeros_like(v), v)
    c = make_cartridge(512, gun=2, case=1)
    m = compare(c.height_um, c.height_um, v, v, pixel_size=c.pixel_size)
    assert m.ccf > 0.99 and min(m.angle, 360 - m.angle) < 0.2
