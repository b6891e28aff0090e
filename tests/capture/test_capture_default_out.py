"""``psbench-capture rig=sim`` exactly as the README shows it: a default folder."""
from __future__ import annotations

import datetime as dt

import pytest

pytest.importorskip("serial")

from psbench.capture.cli import default_out, main  # noqa: E402
from psbench.io import read_dataset  # noqa: E402


def test_capture_without_out_writes_a_new_folder_under_results(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("PSBENCH_RESULTS", raising=False)
    # the README's command, plus keys that keep it small (the folder is what is tested)
    assert main(["rig=sim", "size=32", "targets=none", "progress=false"]) == 0
    printed = capsys.readouterr().out.strip().splitlines()[-1]
    made = sorted((tmp_path / "results" / "captures").iterdir())
    assert len(made) == 1 and made[0].name.startswith("sim_") and made[0].name.endswith("Z")
    assert made[0].resolve() == (tmp_path / printed).resolve()      # prints where it wrote
    assert read_dataset(made[0]).images.shape[0] == 8                # a complete capture
    assert not [p for p in made[0].parent.iterdir() if p.name.startswith(".")]


def test_default_out_follows_psbench_results_and_never_reuses_a_folder(tmp_path, monkeypatch):
    monkeypatch.setenv("PSBENCH_RESULTS", str(tmp_path / "store"))
    now = dt.datetime(2026, 1, 2, 3, 4, 5, tzinfo=dt.timezone.utc)
    first = default_out("sim", now=now)
    assert first == tmp_path / "store" / "captures" / "sim_20260102T030405Z"
    first.mkdir(parents=True)
    second = default_out("sim", now=now)
    assert second.name == "sim_20260102T030405Z-2" and not second.exists()
