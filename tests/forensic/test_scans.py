"""Scan folders (guns.csv) and comparing scans of different pixel sizes."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import psbench as ps
from psbench import PsbenchError
from psbench.forensic import match_pixel_size, match_topographies, read_guns
from psbench.forensic.scans import DEFAULT_X3P, X3P_ENV, resample, scans_folder
from psbench.io import PsbenchWarning

REPO = Path(__file__).resolve().parents[2]


def _folder(tmp_path, scans, csv):
    z = np.zeros((4, 4), np.float32)
    for s in scans:
        ps.io.write_x3p(tmp_path / f"{s}.x3p", z, pixel_size=1.0)
    if csv is not None:
        (tmp_path / "guns.csv").write_text(csv)
    return tmp_path


def test_read_guns(tmp_path):
    root = _folder(tmp_path, ["a1", "a2", "b1"], "scan,gun\na1,1\na2.x3p,1\nb1, 2\n")
    t = read_guns(root)
    assert list(t["scan"]) == ["a1", "a2", "b1"] and list(t["gun"]) == ["1", "1", "2"]
    assert [p.name for p in t["path"]] == ["a1.x3p", "a2.x3p", "b1.x3p"]


@pytest.mark.parametrize("scans, csv, words", [
    (["a1"], None, ["guns.csv", "missing", "scan,gun"]),
    (["a1"], "name,firearm\na1,1\n", ["columns name, firearm", "scan,gun"]),
    (["a1", "a2"], "scan,gun\na1,1\na2,1\nzz9,2\n", ["1 scan(s) with no .x3p", "zz9"]),
    (["a1", "a2", "b7"], "scan,gun\na1,1\na2,1\n", ["does not name 1 .x3p", "b7.x3p"]),
    (["a1"], "scan,gun\na1,1\na1,2\n", ["'a1' is listed more than once"]),
    (["a1"], "scan,gun\na1,\n", ["row 2 has an empty scan or gun"]),
    (["a1"], "scan,gun\n", ["names no scans"]),
])
def test_bad_guns_csv(tmp_path, scans, csv, words):
    root = _folder(tmp_path, scans, csv)
    with pytest.raises(PsbenchError) as exc:
        read_guns(root)
    msg = str(exc.value)
    assert "\n" not in msg and str(root) in msg
    for w in words:
        assert w in msg, msg


def test_missing_folder(tmp_path):
    with pytest.raises(PsbenchError, match=f"does not exist.*{X3P_ENV}"):
        read_guns(tmp_path / "nope")


def test_scans_folder_default(monkeypatch):
    monkeypatch.delenv(X3P_ENV, raising=False)
    assert scans_folder() == Path(DEFAULT_X3P)
    monkeypatch.setenv(X3P_ENV, "/some/where")
    assert scans_folder() == Path("/some/where") and scans_folder("x") == Path("x")


def test_resample_keeps_valid_points_apart():
    z = np.full((8, 8), 5.0, np.float32)
    z[:, :4] = np.nan  # left half not measured (would pull averages down if used as 0)
    out, ok = resample(z, pixel_size=1.0, to=2.0)
    assert out.shape == (4, 4) and ok.shape == (4, 4)
    assert ok[:, 2:].all() and not ok[:, :2].any()
    assert np.allclose(out[ok], 5.0) and np.isnan(out[~ok]).all()
    ramp = np.tile(np.arange(12, dtype=np.float32), (12, 1))
    out, ok = resample(ramp, pixel_size=1.0, to=3.0)
    assert out.shape == (4, 4) and ok.all()
    assert np.allclose(out[0], [1.0, 4.0, 7.0, 10.0])  # means of 3-pixel blocks
    with pytest.raises(PsbenchError, match="to must be a positive"):
        resample(ramp, pixel_size=1.0, to=0)


def test_match_pixel_size_resamples_and_says_so():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(40, 40)).astype(np.float32)
    b = rng.normal(size=(80, 80)).astype(np.float32)
    za, zb, va, vb, px = match_pixel_size(a, b, pixel_size_a=6.25, pixel_size_b=6.25)
    assert px == 6.25 and za.shape == (40, 40) and zb.shape == (80, 80)
    with pytest.warns(PsbenchWarning, match=r"B\.x3p \(3\.125 um per pixel\) resampled to "
                                            r"6\.25 um per pixel to be compared with A\.x3p"):
        za, zb, va, vb, px = match_pixel_size(a, b, pixel_size_a=6.25, pixel_size_b=3.125,
                                              names=("A.x3p", "B.x3p"))
    assert px == 6.25 and za.shape == (40, 40) and zb.shape == (40, 40) and vb.all()


def test_match_topographies_names_files(tmp_path):
    z = np.zeros((16, 16), np.float32)
    pa = ps.io.write_x3p(tmp_path / "coarse.x3p", z[:8, :8], pixel_size=4.0)
    pb = ps.io.write_x3p(tmp_path / "fine.x3p", z, pixel_size=2.0)
    with pytest.warns(PsbenchWarning, match="fine.x3p .2 um per pixel. resampled to 4 um"):
        a, b = match_topographies(pa, pb)
    assert a.pixel_size == b.pixel_size == 4.0 and b.shape == (8, 8) and b.name == "fine"


def test_shared_scans_guns_csv():
    env = os.environ.get(X3P_ENV)
    root = Path(env) if env else REPO.parent / "shared" / "data" / "forensic" / "weller"
    if not (root / "guns.csv").is_file():
        pytest.skip(f"no guns.csv in {root}: set {X3P_ENV} to a folder of .x3p scans with "
                    f"guns.csv (default <repo>/../shared/data/forensic/weller)")
    t = read_guns(root)
    assert len(t) == len(list(root.glob("*.x3p"))) and t["gun"].nunique() > 1
