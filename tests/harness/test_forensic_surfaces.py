"""The main command line on forensic surfaces: cartridge cases and X3P topographies.

A run whose pixel size is known writes its heights as ``height.x3p`` in µm.
"""
from __future__ import annotations

import math

import numpy as np

import psbench as ps

from _cli import run_psbench


def psbench(*args, cwd, timeout=240):
    return run_psbench(*args, cwd=cwd, timeout=timeout)


def test_cartridge_min_size_is_the_generators():
    from psbench.forensic.cartridge import DEFAULT_PIXEL_SIZE, MAX_PIXEL_SIZE
    from psbench.forensic.surface import MIN_SIZE

    assert MIN_SIZE == math.ceil(2048 * DEFAULT_PIXEL_SIZE / MAX_PIXEL_SIZE)
    ps.make_surface("cartridge", size=MIN_SIZE)  # accepted
    try:
        ps.make_surface("cartridge", size=MIN_SIZE - 1)
    except ps.PsbenchError as exc:
        assert "too coarse" in str(exc)
    else:
        raise AssertionError("size below MIN_SIZE was accepted")


def test_cartridge_on_the_command_line(tmp_path):
    r = psbench("surface=cartridge", "size=256", "lights=31x8+62x8", "out=run", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "cartridge@256" in r.stdout and "NE " in r.stdout
    t = ps.io.read_x3p(tmp_path / "run" / "height.x3p")
    assert t.shape == (256, 256)
    assert t.pixel_size == 4.9 * 2048 / 256  # the cartridge's pixel size at this size
    case = ps.make_surface("cartridge", size=256)
    assert np.array_equal(t.valid, case.object_mask)
    # too small: the cartridge's own refusal, before any work, exit status 2
    r = psbench("surface=cartridge", "size=128", cwd=tmp_path)
    assert r.returncode == 2
    assert "too coarse" in r.stderr and "size >= 251" in r.stderr and "Traceback" not in r.stderr


def test_x3p_surface_on_the_command_line(tmp_path):
    yy, xx = np.mgrid[0:64, 0:64].astype(np.float32)
    z = 20.0 * np.exp(-((xx - 32) ** 2 + (yy - 32) ** 2) / 300.0)  # um, a 20 um bump
    z[:4, :] = np.nan
    ps.io.write_x3p(tmp_path / "scan.x3p", z, pixel_size=5.0)
    # Lambertian and noiseless: the normals are exact, so the heights test the units
    r = psbench("surface=scan.x3p", "lights=30x8", "model=lambert", "noise=0", "out=run",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "scan.x3p@64" in r.stdout
    t = ps.io.read_x3p(tmp_path / "run" / "height.x3p")
    assert t.pixel_size == 5.0 and np.array_equal(t.valid, np.isfinite(z))
    # the integrated heights in um are the scan's (up to an offset): um -> px -> um
    d = (t.height - z)[t.valid]
    assert np.abs(d - np.median(d)).max() < 0.05 * 20.0
    # a file that is not an X3P: one line naming it, exit status 2
    (tmp_path / "bad.x3p").write_bytes(b"not a zip")
    r = psbench("surface=bad.x3p", cwd=tmp_path)
    assert r.returncode != 0 and "bad.x3p" in r.stderr and "not a zip" in r.stderr


def test_x3p_as_data_points_to_surface(tmp_path):
    ps.io.write_x3p(tmp_path / "scan.x3p", np.zeros((8, 8), np.float32), pixel_size=5.0)
    r = psbench("data=scan.x3p", cwd=tmp_path)
    assert r.returncode == 2 and "surface=scan.x3p" in r.stderr and "Traceback" not in r.stderr
