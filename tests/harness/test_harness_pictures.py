"""Pictures from the command line: run folders, out= / outputs=, the -m sweep callback
(done/total/ETA, summary best first, comparison sheet), rows that say what each figure is,
"read" for data folders and the far-lights warning."""
import json
import re
import warnings
from pathlib import Path

import cv2
import numpy as np
import pytest

from psbench.harness.run import execute, format_row, normalize
from psbench.harness.store import read_store
from psbench.io import PsbenchWarning

from _cli import clean_env, run_psbench
PICTURES = ("input.png", "truth.png", "normals.png", "error.png", "ne_map.png", "albedo.png",
            "mask.png", "height.png", "run.json")


def psbench(*args, cwd, timeout=180, tmpdir=None):
    env = clean_env() if tmpdir is None else clean_env(TMPDIR=str(tmpdir))
    return run_psbench(*args, cwd=cwd, timeout=timeout, env=env)


def _pictures_line(stdout):
    m = re.search(r"pictures \((\w+), [\d.]+ s\): (\S+)/", stdout)
    assert m, stdout
    return m.group(1), Path(m.group(2))


# ----------------------------------------------------------------------------- rows
def test_format_row_says_what_each_figure_is():
    row = dict(kind="solve", surface="sombrero2", size=512, lights="45x8", model="ts",
               noise=0.05, mask="Th", method="ps", ne_mean=9.22, ne_median=7.15, ie_l2=0.2862,
               ie_rel=10.76, qf_hi=0.7, qf_sh=0.5, qf_total=0.72, t_total=1.3, t_render=0.4,
               t_solve=0.4, status="ok")
    line = format_row(row)
    for part in ("NE 9.22° mean angular error (median 7.15°)", "IE 0.2862 L2 Lambert residual "
                 "(10.76 % of range)", "QF 0.72 mask vs true highlights/shadows", "render 0.40"):
        assert part in line, line
    data = dict(row, data="/x/catPNG", surface=None, ne_mean=None, qf_total=None, n_images=96,
                lights=None)
    line = format_row(data)
    assert "read 0.40" in line and "render" not in line, line
    assert "lights: all 96 read" in line and "NE - (no ground truth)" in line
    cfg = {"lights_read": {"requested": "80x8", "images": list(range(1, 9)), "available": 96,
                           "max_off_deg": 54.2, "off_deg": [54.2] * 8, "zenith_deg": [40] * 8}}
    line = format_row(dict(data, lights="80x8", config=json.dumps(cfg)))
    assert "lights=80x8 -> nearest 8 of 96 read (up to 54.2° off)" in line, line


def _folder(tmp_path, spec="30x12"):
    import psbench as ps

    s = ps.make_surface("semisphere", size=24)
    lay = ps.layout(spec)
    sc = ps.render(s, lay, model="lambert", noise=0.0)
    return ps.io.write_dataset(tmp_path / "obj", sc.images, lay, object_mask=s.object_mask,
                               normals=s.normals)


def test_far_lights_warn_and_record_the_lights_used(tmp_path):
    d = _folder(tmp_path)
    with pytest.warns(PsbenchWarning, match=r"lights=80x8: 8 of the 8 lights used are more "
                                            r"than 10 deg .*up to 5\d\.\d deg"):
        row = execute(normalize({"data": str(d), "lights": "80x8", "mask": "None"}))
    assert row["status"] == "ok"
    used = json.loads(row["config"])["lights_read"]
    assert used["requested"] == "80x8" and len(used["images"]) == 8 and used["available"] == 12
    assert used["max_off_deg"] > 45 and all(25 < z < 35 for z in used["zenith_deg"])
    assert "read" in format_row(row) and "up to 5" in format_row(row)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PsbenchWarning)     # near lights: no warning
        row = execute(normalize({"data": str(d), "lights": "30x4", "mask": "None"}))
    assert json.loads(row["config"])["lights_read"]["max_off_deg"] < 10


# ----------------------------------------------------------------------------- single runs
def test_single_run_pictures_out_and_outputs(tmp_path):
    r = psbench("size=48", "surface=spheres", "outputs=all", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lvl, d = _pictures_line(r.stdout)
    assert lvl == "all" and d.parent == tmp_path / "results" / "out" / "adhoc"
    for f in PICTURES + ("mesh.ply", "mesh.obj", "normals.npz", "height.npz"):
        assert (d / f).is_file(), f
    info = json.loads((d / "run.json").read_text())
    assert info["run_id"] == d.name and "mean angular error" in info["row"]
    # the stored row and the pictures agree
    df = read_store(tmp_path / "results")
    ne = np.load(d / "ne.npz")["ne"]
    assert np.nanmean(ne) == pytest.approx(df.loc[0, "ne_mean"], rel=1e-4)
    # albedo scaled by a robust percentile: its 99th percentile over the object is white
    obj = cv2.imread(str(d / "object_mask.png"), cv2.IMREAD_UNCHANGED) > 0
    alb = cv2.imread(str(d / "albedo.png"), cv2.IMREAD_GRAYSCALE)
    assert np.percentile(alb[obj], 99) >= 250 and np.median(alb[obj]) > 60
    # out=DIR: the pictures go there; outputs=pictures (default): no arrays or meshes
    r = psbench("size=48", "surface=spheres", "out=pics", "rerun=true", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    lvl, d2 = _pictures_line(r.stdout)
    assert lvl == "pictures" and d2 == tmp_path / "pics"
    assert (d2 / "normals.png").is_file() and not list(d2.glob("*.np[yz]"))
    assert not (d2 / "mesh.obj").exists()
    # out=DIR on the stored run: the pictures written when it ran are copied there
    r = psbench("size=48", "surface=spheres", "out=pics_again", cwd=tmp_path)
    assert r.returncode == 0 and "skipped (stored)" in r.stdout, r.stderr
    assert "pictures (stored run, copied from" in r.stdout, r.stdout
    for f in PICTURES:
        assert (tmp_path / "pics_again" / f).is_file(), f
    # a folder psbench did not write is refused before any work
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("keep me")
    r = psbench("size=40", "surface=spheres", "out=mine", cwd=tmp_path)
    assert r.returncode == 2 and "holds files psbench did not write" in r.stderr
    assert "Traceback" not in r.stderr and (tmp_path / "mine" / "notes.txt").is_file()
    assert len(read_store(tmp_path / "results")) == 1          # nothing stored for it
    # outputs=none: no pictures
    r = psbench("size=40", "surface=spheres", "outputs=none", cwd=tmp_path)
    assert r.returncode == 0 and "pictures (" not in r.stdout
    # stored without pictures: not redone, says how to make them
    r = psbench("size=40", "surface=spheres", cwd=tmp_path)
    assert r.returncode == 0 and "skipped (stored)" in r.stdout
    assert "no pictures in" in r.stdout and "rerun=true" in r.stdout
    # runs that solve nothing have no pictures and no note
    r = psbench("kind=cond", "lights=30x8+60x8", cwd=tmp_path)
    assert r.returncode == 0 and "cond=" in r.stdout
    assert "pictures (" not in r.stdout and "no pictures" not in r.stdout


# ----------------------------------------------------------------------------- sweeps
def _check_sheet(folder, n_cols):
    png, html = folder / "comparison.png", folder / "comparison.html"
    assert png.is_file() and html.is_file()
    img = cv2.imread(str(png))
    assert img.shape[1] >= n_cols * 200 and img.std() > 20
    text = html.read_text()
    for ref in re.findall(r"(?:src|href)=[\"']([^\"'#]+)[\"']", text):
        assert (folder / ref).exists(), ref
    assert "](" not in text and "**" not in text            # no raw Markdown
    return text


def test_sweep_progress_summary_and_sheet(tmp_path):
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    args = ["-m", "mask=None,Th,Th-Hi-Re-Sh", "method=ps", "size=32", "hydra/launcher=basic"]
    r = psbench(*args, cwd=tmp_path, tmpdir=tmp)
    assert r.returncode == 0, r.stderr
    for k in (1, 2, 3):
        assert f"sweep mask=None,Th,Th-Hi-Re-Sh: {k}/3 done" in r.stderr, r.stderr
    assert "ETA" in r.stderr
    out = r.stdout
    assert "best first" in out
    table = out[out.index("best first"):].splitlines()[3:6]
    ne = [float(ln.split()[2]) for ln in table]
    assert ne == sorted(ne) and len(ne) == 3
    assert {ln.split()[1] for ln in table} == {"None", "Th", "Th-Hi-Re-Sh"}
    folder = tmp_path / "results" / "out" / "mask=None,Th,Th-Hi-Re-Sh"   # named from the sweep
    assert f"comparison sheet: {folder / 'comparison.html'}" in out
    text = _check_sheet(folder, 3)
    assert text.replace(folder.name, "").count("mask=") == 0 and "Th-Hi-Re-Sh" in text
    assert len([p for p in folder.iterdir() if p.is_dir()]) == 3
    assert list(tmp.iterdir()) == []                         # the progress file is gone
    r = psbench(*args, cwd=tmp_path, tmpdir=tmp)             # stored: no work, same summary
    assert r.returncode == 0 and r.stdout.count("skipped (stored)") == 3
    assert "3/3 done" in r.stderr and "best first" in r.stdout
    sheet = (folder / "comparison.html").read_text()
    r = psbench("-m", "mask=None,Th", "method=ps", "size=32", "hydra/launcher=basic",
                cwd=tmp_path, tmpdir=tmp)                # another sweep: its own folder
    assert r.returncode == 0, r.stderr
    _check_sheet(tmp_path / "results" / "out" / "mask=None,Th", 2)
    assert (folder / "comparison.html").read_text() == sheet     # the first sheet is kept


def test_sweep_in_joblib_workers(tmp_path):
    r = psbench("-m", "method=ps,robust", "mask=None", "size=24", "hydra.launcher.n_jobs=2",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "sweep method=ps,robust: 2/2 done" in r.stderr and "best first" in r.stdout
    _check_sheet(tmp_path / "results" / "out" / "method=ps,robust", 2)


def test_sheet_without_ground_truth(tmp_path):
    """Real data without ground truth: rows input and normals only, no NE colour bar."""
    import psbench as ps
    from psbench.harness.sheet import build_sheet

    s = ps.make_surface("spheres", size=32)
    lay = ps.layout("45x8")
    sc = ps.render(s, lay, model="ts", noise=0.0)
    runs = []
    for i, mask in enumerate(("None", "Th")):
        res = ps.solve(sc.images, lay, mask=mask, object_mask=s.object_mask)
        d = tmp_path / f"run{i}"
        ps.io.write_outputs(d, res, object_mask=s.object_mask, images=sc.images, arrays=False,
                            ply=False, obj=False)
        (d / "run.json").write_text(json.dumps({"files": ["normals.png", "input.png"]}))
        runs.append(({"run_id": f"run{i}", "mask": mask, "status": "ok", "ne_mean": None,
                      "ie_rel": 1.0 + i}, d))
    png, html = build_sheet(runs, tmp_path)
    img = cv2.imread(str(png))
    assert 2 * 320 < img.shape[0] < 3 * 320               # two rows of 320 px tiles
    text = _check_sheet(tmp_path, 2)
    assert "NE map" not in text and "no truth" not in text


@pytest.mark.realdata
def test_data_folder_pictures_read_and_far_lights(tmp_path, diligent):
    cat = diligent / "cat"
    r = psbench(f"data={cat}", "mask=None", "lights=80x8", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "psbench: warning: lights=80x8" in r.stderr and "Traceback" not in r.stderr
    line = next(ln for ln in r.stdout.splitlines() if "| stored " in ln)
    assert "-> nearest 8 of 96 read (up to" in line and "(read " in line
    assert "render" not in line
    _, d = _pictures_line(r.stdout)
    for f in PICTURES:
        assert (d / f).is_file(), f
    assert json.loads((d / "run.json").read_text())["lights_read"]["max_off_deg"] > 10
    r = psbench("-m", f"data={cat}", "mask=None,Th", "hydra/launcher=basic", "sweep=cat",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("lights: all 96 read") == 2 and "2/2 done" in r.stderr
    _check_sheet(tmp_path / "results" / "out" / "cat", 2)


def test_rank_and_summary_table():
    from psbench.harness.sweep import rank, summary_table, varying

    rows = [dict(run_id="a", mask="Th", method="ps", ne_mean=9.2, ie_rel=10.0, status="ok"),
            dict(run_id="b", mask="RA", method="ps", ne_mean=None, ie_rel=1.0, status="failed"),
            dict(run_id="c", mask="None", method="ps", ne_mean=8.1, ie_rel=5.0, status="ok"),
            dict(run_id="d", mask="NL", method="ps", ne_mean=None, ie_rel=3.0, status="ok")]
    assert [r["run_id"] for r in rank(rows)] == ["c", "a", "d", "b"]   # NE, then IE, failed
    assert varying(rows) == ["mask"]
    lines = summary_table(rows).splitlines()
    assert lines[0].split()[:3] == ["#", "mask", "NE"]
    assert [ln.split()[1] for ln in lines[2:]] == ["None", "Th", "NL", "RA"]
    assert lines[-1].rstrip().endswith("failed") and lines[-1] == lines[-1].rstrip()
