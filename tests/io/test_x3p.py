"""X3P (ISO 25178-72) in and out: round trips, units, checksums, metadata, bad files.

Small files are written by the tests; the real-scan tests read the shared breech-face scans
($PSBENCH_X3P, default <repo>/../shared/data/forensic/weller) and skip when they are absent.
"""
from __future__ import annotations

import os
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest
import x3pio

import psbench as ps
from psbench import PsbenchError

REPO = Path(__file__).resolve().parents[2]


def _scans():
    env = os.environ.get("PSBENCH_X3P")
    root = Path(env) if env else REPO.parent / "shared" / "data" / "forensic" / "weller"
    files = sorted(root.glob("*.x3p")) if root.is_dir() else []
    if not files:
        pytest.skip(f"no X3P scans in {root}: set PSBENCH_X3P to a folder of .x3p files "
                    f"(default <repo>/../shared/data/forensic/weller)")
    return files


def _height(shape=(12, 17), seed=0):
    rng = np.random.default_rng(seed)
    z = rng.normal(0.0, 3.0, shape).astype(np.float32)  # um
    z[2, 3] = np.nan
    z[5, :4] = np.nan
    return z


META = {"date": "2024-05-01T10:20:30+00:00", "creator": "lab A", "comment": "breech face",
        "instrument": {"manufacturer": "Acme", "model": "Scope", "serial": "42",
                       "version": "1.0"},
        "probing_type": "NonContacting", "probing_identification": "20x"}


def test_round_trip_small_file(tmp_path):
    z = _height()
    path = ps.io.write_x3p(tmp_path / "a.x3p", z, pixel_size=3.125, **META)
    t = ps.io.read_x3p(path)
    assert isinstance(t, ps.io.Topography) and isinstance(t, ps.Topography)
    assert t.height.dtype == np.float32 and t.valid.dtype == bool and t.shape == z.shape
    assert np.array_equal(t.height, z, equal_nan=True)  # float32 um -> m -> um is exact
    assert np.array_equal(t.valid, np.isfinite(z)) and t.valid.sum() == z.size - 5
    assert t.pixel_size == 3.125 and t.name == "a"
    for key, value in META.items():
        assert t.meta[key] == value
    again = ps.io.read_x3p(ps.io.write_x3p(tmp_path / "b.x3p", t.height,
                                           pixel_size=t.pixel_size, valid=t.valid, **t.meta))
    assert np.array_equal(again.height, t.height, equal_nan=True)
    assert again.meta == t.meta and again.pixel_size == t.pixel_size


def test_file_is_in_metres_with_checksums(tmp_path):
    z = _height()
    path = ps.io.write_x3p(tmp_path / "a.x3p", z, pixel_size=6.25)
    f = x3pio.read(path, verify=True)  # raises on a wrong MD5 of main.xml or data.bin
    assert f.header.x.increment == pytest.approx(6.25e-6, rel=1e-12)
    assert f.header.y.increment == pytest.approx(6.25e-6, rel=1e-12)
    ok = np.isfinite(z)
    assert np.allclose(f.layers[0].z[ok], z[ok].astype(np.float64) * 1e-6, rtol=1e-12, atol=0)
    assert np.isnan(f.layers[0].z[~ok]).all()
    names = zipfile.ZipFile(path).namelist()
    assert "md5checksum.hex" in names and "bindata/data.bin" in names
    # defaults: psbench as the software that made the data
    t = ps.io.read_x3p(path)
    assert t.meta["instrument"]["manufacturer"] == "psbench"
    assert t.meta["probing_type"] == "Software" and t.meta["date"]


def test_valid_argument_writes_nan(tmp_path):
    z = np.arange(20, dtype=np.float32).reshape(4, 5)
    valid = np.ones_like(z, bool)
    valid[1, 2] = valid[3, 4] = False
    t = ps.io.read_x3p(ps.io.write_x3p(tmp_path / "v.x3p", z, pixel_size=1.0, valid=valid))
    assert np.array_equal(t.valid, valid) and np.isnan(t.height[~valid]).all()
    assert np.array_equal(t.height[valid], z[valid])


def test_validity_file_is_read_as_invalid(tmp_path):
    """A file's validity mask (bindata/valid.bin, written for integer heights) clears points."""
    z = np.array([[1.0, 2.0, np.nan], [4.0, np.nan, 6.0]]) * 1e-6
    path = tmp_path / "int.x3p"
    x3pio.write(path, z, x_scale=2e-6, y_scale=2e-6, z_type=x3pio.DataType.INT32)
    assert "bindata/valid.bin" in zipfile.ZipFile(path).namelist()
    t = ps.io.read_x3p(path)
    assert np.array_equal(t.valid, np.isfinite(z)) and t.pixel_size == 2.0
    assert np.allclose(t.height[t.valid], z[np.isfinite(z)] * 1e6, atol=1e-3)


def test_surface_from_x3p(tmp_path):
    yy, xx = np.mgrid[0:32, 0:40]
    z = (0.5 * xx + 0.25 * yy).astype(np.float32)  # um
    z[:3, :3] = np.nan
    path = ps.io.write_x3p(tmp_path / "ramp.x3p", z, pixel_size=2.0)
    s = ps.surface_from_file(path)
    assert s.name == "ramp" and s.shape == z.shape
    ok = np.isfinite(z)
    assert np.array_equal(s.object_mask, ok)
    assert np.allclose(s.height[ok], z[ok] / 2.0, atol=1e-5)  # um / (um per px) = px
    assert np.isfinite(s.height).all()
    # slope dz/dcol = 0.5 um per px of 2 um = 0.25 px/px -> normal's x = -0.25 / |.|
    inner = s.normals[10:20, 10:20]
    n = np.array([-0.25, 0.125, 1.0]) / np.linalg.norm([-0.25, 0.125, 1.0])
    assert np.allclose(inner, n, atol=1e-4)
    roi = np.zeros(z.shape, bool)
    roi[:, :20] = True
    s2 = ps.surface_from_file(path, object_mask=roi, scale=2.0)
    assert np.array_equal(s2.object_mask, roi & ok)
    assert np.allclose(s2.height[ok], z[ok], atol=1e-5)


# ------------------------------------------------------------------------ bad input
def _rezip(src, dst, *, drop=None, corrupt=None):
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for name in zin.namelist():
            if name == drop:
                continue
            data = zin.read(name)
            if name == corrupt:
                data = data[:-1] + bytes([data[-1] ^ 1])
            zout.writestr(name, data)
    return dst


@pytest.fixture
def good(tmp_path):
    return ps.io.write_x3p(tmp_path / "good.x3p", _height(), pixel_size=6.25)


def _one_line(exc, *words):
    msg = str(exc.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_not_a_zip(tmp_path):
    p = tmp_path / "scan.x3p"
    p.write_bytes(b"this is not a zip archive")
    with pytest.raises(PsbenchError) as exc:
        ps.io.read_x3p(p)
    _one_line(exc, str(p), "not a zip", "expected an ISO 25178-72 X3P")


def test_wrong_md5(tmp_path, good):
    bad = _rezip(good, tmp_path / "bad.x3p", corrupt="bindata/data.bin")
    with pytest.raises(PsbenchError) as exc:
        ps.io.read_x3p(bad)
    _one_line(exc, str(bad), "MD5", "bindata/data.bin")


def test_missing_bindata(tmp_path, good):
    bad = _rezip(good, tmp_path / "nobin.x3p", drop="bindata/data.bin")
    with pytest.raises(PsbenchError) as exc:
        ps.io.read_x3p(bad)
    _one_line(exc, str(bad), "bindata/data.bin", "missing")


def test_missing_file():
    with pytest.raises(PsbenchError, match="does not exist"):
        ps.io.read_x3p("/nonexistent/scan.x3p")


def test_profile_and_point_cloud(tmp_path):
    prof = tmp_path / "profile.x3p"
    x3pio.write(prof, np.zeros(10), x_scale=1e-6)
    with pytest.raises(PsbenchError) as exc:
        ps.io.read_x3p(prof)
    _one_line(exc, str(prof), "profile", "expected an ISO 25178-72 X3P surface")
    cloud = tmp_path / "cloud.x3p"
    x3pio.write_points(cloud, np.zeros((5, 3)))
    with pytest.raises(PsbenchError) as exc:
        ps.surface_from_file(cloud)
    _one_line(exc, str(cloud), "point cloud")


def test_increments_in_micrometres(tmp_path):
    p = tmp_path / "um.x3p"
    x3pio.write(p, np.zeros((4, 4)), x_scale=6.25, y_scale=6.25)  # um written as metres
    with pytest.raises(PsbenchError) as exc:
        ps.io.read_x3p(p)
    _one_line(exc, str(p), "6.25 m per pixel", "in um", "metres")


def test_heights_in_micrometres(tmp_path):
    p = tmp_path / "zum.x3p"
    z = np.random.default_rng(0).normal(0, 5.0, (8, 8))  # um values written as metres
    x3pio.write(p, z, x_scale=6.25e-6, y_scale=6.25e-6)
    with pytest.raises(PsbenchError) as exc:
        ps.io.read_x3p(p)
    _one_line(exc, str(p), "heights", "in um")


def test_unequal_increments_and_layers(tmp_path):
    p = tmp_path / "rect.x3p"
    x3pio.write(p, np.zeros((4, 4)), x_scale=1e-6, y_scale=2e-6)
    with pytest.raises(PsbenchError, match="square pixels"):
        ps.io.read_x3p(p)
    p2 = tmp_path / "layers.x3p"
    x3pio.write(p2, np.zeros((2, 4, 4)), x_scale=1e-6, y_scale=1e-6)
    with pytest.raises(PsbenchError, match="2 surface layers"):
        ps.io.read_x3p(p2)


def test_write_refuses_bad_arguments(tmp_path):
    z = np.zeros((4, 4), np.float32)
    with pytest.raises(PsbenchError, match="pixel_size"):
        ps.io.write_x3p(tmp_path / "a.x3p", z, pixel_size=0)
    with pytest.raises(PsbenchError, match="end in .x3p"):
        ps.io.write_x3p(tmp_path / "a.png", z, pixel_size=1)
    with pytest.raises(PsbenchError, match=r"shape \(H, W\)"):
        ps.io.write_x3p(tmp_path / "a.x3p", np.zeros(4), pixel_size=1)
    with pytest.raises(PsbenchError, match="unknown metadata 'author'"):
        ps.io.write_x3p(tmp_path / "a.x3p", z, pixel_size=1, author="me")
    with pytest.raises(PsbenchError, match="probing_type"):
        ps.io.write_x3p(tmp_path / "a.x3p", z, pixel_size=1, probing_type="laser")
    with pytest.raises(PsbenchError, match="valid must have shape"):
        ps.io.write_x3p(tmp_path / "a.x3p", z, pixel_size=1, valid=np.ones((3, 3), bool))
    assert not list(tmp_path.iterdir())  # nothing written, no temporary file left


# ------------------------------------------------------------------------ real scans
def test_real_scan_reads_with_metadata():
    t = ps.io.read_x3p(_scans()[0])
    assert t.height.ndim == 2 and t.height.dtype == np.float32
    assert 0.1 < t.pixel_size < 100  # um
    v = t.height[t.valid]
    assert 0.05 < t.valid.mean() < 1 and np.isfinite(v).all() and np.isnan(t.height[~t.valid]).all()
    assert 0.1 < np.ptp(v) < 1000  # a breech face spans um, not m or nm
    assert t.meta.get("date")


def test_real_scan_round_trip(tmp_path):
    src = _scans()[0]
    t = ps.io.read_x3p(src)
    out = ps.io.write_x3p(tmp_path / "copy.x3p", t.height, pixel_size=t.pixel_size,
                          valid=t.valid, **t.meta)
    b = ps.io.read_x3p(out)
    assert np.array_equal(b.height, t.height, equal_nan=True) and np.array_equal(b.valid, t.valid)
    assert b.pixel_size == t.pixel_size and b.meta == t.meta
    # the original file's metres agree with psbench's copy to float32 precision
    with warnings.catch_warnings():  # x3pio multiplies the NaN points by the increment
        warnings.simplefilter("ignore", RuntimeWarning)
        orig, copy = x3pio.read(src).layers[0].z, x3pio.read(out).layers[0].z
    ok = np.isfinite(orig)
    assert np.array_equal(ok, np.isfinite(copy))
    assert np.allclose(copy[ok], orig[ok], rtol=1e-6, atol=1e-13)


@pytest.mark.slow
def test_every_real_scan_round_trips(tmp_path):
    for src in _scans():
        t = ps.io.read_x3p(src)
        b = ps.io.read_x3p(ps.io.write_x3p(tmp_path / "rt.x3p", t.height,
                                           pixel_size=t.pixel_size, valid=t.valid, **t.meta))
        assert np.array_equal(b.height, t.height, equal_nan=True), src.name
        assert np.array_equal(b.valid, t.valid) and b.pixel_size == t.pixel_size, src.name
        assert b.meta == t.meta, src.name


def test_real_scan_as_surface():
    src = _scans()[0]
    t = ps.io.read_x3p(src)
    s = ps.surface_from_file(src)
    assert np.array_equal(s.object_mask, t.valid)
    assert np.allclose(s.height[t.valid], t.height[t.valid] / t.pixel_size, rtol=1e-5, atol=1e-6)



def test_other_reader_reads_psbench_files(tmp_path):
    """surfalize (an independent X3P reader) sees the same grid, heights and holes."""
    surfalize = pytest.importorskip("surfalize", reason="surfalize is not installed "
                                    "(pip install surfalize) to cross-check X3P files")
    z = _height((20, 30))
    path = ps.io.write_x3p(tmp_path / "x.x3p", z, pixel_size=6.25)
    s = surfalize.Surface.load(path)
    assert s.data.shape == z.shape
    assert s.step_x == pytest.approx(6.25) and s.step_y == pytest.approx(6.25)  # um
    assert np.array_equal(np.isnan(s.data), np.isnan(z))
    assert np.allclose(s.data[np.isfinite(z)], z[np.isfinite(z)], atol=1e-6)


def test_topography_checks_its_fields():
    t = ps.Topography(height=[[1, 2], [np.nan, 4]], valid=None, pixel_size=2)
    assert t.height.dtype == np.float32 and t.pixel_size == 2.0
    assert t.valid.tolist() == [[True, True], [False, True]]  # NaN is never valid
    with pytest.raises(PsbenchError, match="pixel_size must be a positive"):
        ps.Topography(height=np.zeros((2, 2)), valid=None, pixel_size=-1)
    with pytest.raises(PsbenchError, match=r"valid must have shape \(2, 2\)"):
        ps.Topography(height=np.zeros((2, 2)), valid=np.ones((3, 3), bool), pixel_size=1)
    with pytest.raises(PsbenchError, match=r"height must have shape \(H, W\)"):
        ps.Topography(height=np.zeros(4), valid=None, pixel_size=1)
