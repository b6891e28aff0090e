"""``psbench-forensic``: reconstruct and compare, run in-process through ``main(args)``."""
from __future__ import annotations

import numpy as np
import pytest

import psbench as ps
from psbench import io
from psbench.forensic.cli import main


def _run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def _error(err):
    lines = [ln for ln in err.splitlines() if ln.startswith("psbench-forensic: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("cmd, options", [
    ("compare", ("A.x3p", "B.x3p", "--picture", "--no-picture", "--json")),
    ("reconstruct", ("FOLDER", "--out", "--pixel-size", "--png", "--calibration",
                     "--creator")),
])
def test_help_documents_every_option(capsys, cmd, options):
    with pytest.raises(SystemExit) as exc:
        main([cmd, "--help"])
    assert exc.value.code == 0
    text = capsys.readouterr().out
    for opt in options:
        assert opt in text, opt
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "compare" in capsys.readouterr().out


def _capture(folder, *, size=48):
    s = ps.make_surface("semisphere_disc", size=size)
    lay = ps.layout("30x4+60x4")
    io.write_dataset(folder, ps.render(s, lay, model="lambert").images, lay,
                     object_mask=s.object_mask)
    return s


def test_reconstruct_with_pixel_size(tmp_path, capsys):
    s = _capture(tmp_path / "cap")
    code, out, err = _run(capsys, "reconstruct", str(tmp_path / "cap"), "--out",
                          str(tmp_path / "h.x3p"), "--pixel-size", "5", "--creator", "lab")
    assert code == 0, err
    assert "read 8 images of 48 x 48" in err and "pixel 5 um from --pixel-size" in err
    assert "h.x3p: 48 x 48 heights at 5 um" in out
    t = io.read_x3p(tmp_path / "h.x3p")
    assert t.pixel_size == 5.0 and t.meta["creator"] == "lab"
    assert np.array_equal(t.valid, s.object_mask)
    # a hemisphere at 5 um per pixel: away from its vertical rim (zenith < 60 deg, where
    # integration of exact normals is well posed) the heights in um follow it
    inner = t.valid & (s.zenith < 60)
    z, truth = t.height[inner], s.height[inner] * 5.0
    assert np.corrcoef(z, truth)[0, 1] > 0.99
    assert np.ptp(z) == pytest.approx(np.ptp(truth), rel=0.15)
    png = tmp_path / "h.png"
    assert png.is_file() and png.stat().st_size > 1000


def test_reconstruct_pixel_size_from_calibration(tmp_path, capsys):
    from psbench.calibrate import Calibration

    _capture(tmp_path / "cap", size=32)
    io.save_calibration(Calibration(pixel_size=0.0049), tmp_path / "cap" / "calibration")
    code, out, err = _run(capsys, "reconstruct", str(tmp_path / "cap"), "--out",
                          str(tmp_path / "o" / "h.x3p"), "--png", str(tmp_path / "view.png"))
    assert code == 0, err
    assert "pixel 4.9 um from the calibration" in err
    assert io.read_x3p(tmp_path / "o" / "h.x3p").pixel_size == pytest.approx(4.9)
    assert (tmp_path / "view.png").is_file()


@pytest.mark.parametrize("extra, words", [
    ((), ["no pixel size", "--pixel-size UM"]),
    (("--pixel-size", "-2"), ["--pixel-size must be a positive"]),
    (("--pixel-size", "abc"), ["invalid float value"]),
])
def test_reconstruct_bad_pixel_size(tmp_path, capsys, extra, words):
    _capture(tmp_path / "cap", size=32)
    code, out, err = _run(capsys, "reconstruct", str(tmp_path / "cap"), "--out",
                          str(tmp_path / "h.x3p"), *extra)
    assert code == 2
    line = _error(err)
    for w in words:
        assert w in line, line
    assert not (tmp_path / "h.x3p").exists()


def test_reconstruct_bad_arguments(tmp_path, capsys):
    code, _, err = _run(capsys, "reconstruct", str(tmp_path / "none"), "--out", "h.x3p")
    assert code == 2 and "is not a folder" in _error(err)
    code, _, err = _run(capsys, "reconstruct", str(tmp_path), "--out", "h.npy")
    assert code == 2 and "expected a .x3p file" in _error(err)
    code, _, err = _run(capsys, "reconstruct", str(tmp_path))
    assert code == 2 and "--out" in _error(err)


def test_compare_refuses_bad_files(tmp_path, capsys):
    good = io.write_x3p(tmp_path / "a.x3p", np.zeros((8, 8), np.float32), pixel_size=5.0)
    (tmp_path / "b.x3p").write_bytes(b"not a zip")
    code, _, err = _run(capsys, "compare", str(good), str(tmp_path / "b.x3p"), "--no-picture")
    assert code == 2
    line = _error(err)
    assert "b.x3p" in line and "not a zip" in line
    code, _, err = _run(capsys, "compare", str(good), str(tmp_path / "b.png"))
    assert code == 2 and "expected an .x3p file" in _error(err)
    code, _, err = _run(capsys, "compare", str(good))
    assert code == 2 and "B.x3p" in _error(err)
    code, _, err = _run(capsys, "compare", str(good), str(good), "--picture", "x.jpg")
    assert code == 2 and "expected a .png file" in _error(err)


def _field(seed, size=200, disc=True):
    """Band-limited random heights (um) on a disc, like a breech face."""
    import cv2

    rng = np.random.default_rng(seed)
    z = cv2.GaussianBlur(rng.standard_normal((size, size)).astype(np.float32), (0, 0), 2.0)
    if not disc:
        return z
    yy, xx = np.mgrid[:size, :size] - (size - 1) / 2
    return np.where(np.hypot(yy, xx) < 0.47 * size, z, np.nan).astype(np.float32)


def test_compare_same_and_different_source(tmp_path, capsys):
    import json

    z = _field(0)
    disc = np.isfinite(z)
    full = _field(0, disc=False)
    # the same surface moved 6 px (37.5 um) to the right under the same disc (the pose is
    # relative to the centres of the valid regions, which stay put)
    shifted = np.full_like(z, np.nan)
    shifted[:, 6:] = full[:, :-6]
    shifted[~disc] = np.nan
    a = io.write_x3p(tmp_path / "a.x3p", z, pixel_size=6.25)
    b = io.write_x3p(tmp_path / "b.x3p", shifted, pixel_size=6.25)
    c = io.write_x3p(tmp_path / "c.x3p", _field(1), pixel_size=6.25)
    code, out, err = _run(capsys, "compare", str(a), str(b), "--json", "--picture",
                          str(tmp_path / "ab.png"))
    assert code == 0, err
    r = json.loads(out)
    assert r["match"] and r["count"] >= 0.8 * r["cells"] and r["ccf"] > 0.9
    # laying b on a moves it 6 px left: dx = -37.5 um
    assert r["pose"]["dx_um"] == pytest.approx(-37.5, abs=6.25)
    assert abs(r["pose"]["dy_um"]) <= 6.25 and abs(r["pose"]["theta_deg"]) <= 1.0
    assert (tmp_path / "ab.png").is_file() and r["picture"] == str(tmp_path / "ab.png")
    code, out, err = _run(capsys, "compare", str(a), str(c), "--no-picture", "--json")
    assert code == 0, err
    # the command reports what psbench.forensic.cmc finds
    from psbench.forensic import cmc

    ta, tc = io.read_x3p(a), io.read_x3p(c)
    ref = cmc(ta.height, tc.height, ta.valid, tc.valid, pixel_size=6.25)
    r = json.loads(out)
    assert r["count"] == ref.count and r["ccf"] == pytest.approx(ref.ccf) and r["ccf"] < 0.2
    assert r["pose"]["theta_deg"] == pytest.approx(ref.pose.theta)
    code, out, err = _run(capsys, "compare", str(a), str(c), "--no-picture")
    assert code == 0 and f"a.x3p vs c.x3p: CCFmax {ref.ccf:.3f} | CMC {ref.count} of" in out


def test_compare_resamples_and_says_so(tmp_path, capsys, monkeypatch):
    import cv2

    z = _field(0)
    fine = cv2.resize(np.nan_to_num(z), (400, 400), interpolation=cv2.INTER_LINEAR)
    fine[cv2.resize(np.isnan(z).astype(np.uint8), (400, 400),
                    interpolation=cv2.INTER_NEAREST) > 0] = np.nan
    a = io.write_x3p(tmp_path / "a.x3p", z, pixel_size=6.25)
    b = io.write_x3p(tmp_path / "fine.x3p", fine, pixel_size=3.125)
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PSBENCH_RESULTS", raising=False)
    code, out, err = _run(capsys, "compare", str(a), str(b))
    assert code == 0, err
    assert "fine.x3p (3.125 um per pixel) resampled to 6.25 um per pixel" in err
    assert "(match)" in out and "pixel 6.25 um" in out
    # the default picture: under the results folder, not in the working folder
    assert (tmp_path / "results" / "out" / "compare" / "a_vs_fine_cmc.png").is_file()
    assert not list(tmp_path.glob("*.png"))


@pytest.mark.slow
def test_compare_real_scans(tmp_path, capsys):
    from pathlib import Path

    from psbench.forensic import read_guns

    try:
        guns = read_guns()
    except ps.PsbenchError as exc:
        pytest.skip(f"no shared scans ({exc}); set PSBENCH_X3P")
    same = guns[guns["gun"] == guns["gun"].iloc[0]]["path"].tolist()[:2]
    other = guns[guns["gun"] != guns["gun"].iloc[0]]["path"].iloc[0]
    code, out, err = _run(capsys, "compare", str(same[0]), str(same[1]), "--picture",
                          str(tmp_path / "same.png"))
    assert code == 0 and "(match)" in out, err
    code, out, err = _run(capsys, "compare", str(same[0]), str(Path(other)), "--no-picture")
    assert code == 0 and "(no match)" in out, err
