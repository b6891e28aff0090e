"""Harness: results store, schema, compaction, grid expansion, sharded execution.

Independent of the numerical modules: runs use ``kind: noop`` (the harness's
self-test kind) except where noted.
"""
import json
import warnings

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from psbench import PsbenchError
from psbench.harness import grid, run, shards, store
from psbench.harness.schema import COLUMNS, META_KEY, SCHEMA_VERSION


def _row(rid, sweep="s", utc=None, **kw):
    import datetime as dt

    r = dict(run_id=rid, sweep=sweep, status="ok", kind="noop", ne_mean=1.0)
    if utc is not None:
        r["utc"] = dt.datetime(2026, 1, 1, tzinfo=dt.timezone.utc) + dt.timedelta(seconds=utc)
    r.update(kw)
    return r


def test_schema_version_and_columns(tmp_path):
    p = store.write_row(tmp_path, _row("a1"))
    assert p == tmp_path / "runs" / "s" / "a1.parquet"
    f = pq.ParquetFile(p)
    assert f.schema_arrow.metadata[META_KEY] == str(SCHEMA_VERSION).encode()
    assert f.schema_arrow.names == list(COLUMNS)
    df = store.read_store(tmp_path)
    assert list(df.columns) == list(COLUMNS)
    assert df.loc[0, "schema_version"] == SCHEMA_VERSION
    for c in ("ne_mean", "ne_lt5", "ie_rel", "qf_total", "peak_mem_mb", "git_sha", "libs",
              "config", "status", "error", "thresholds", "seed", "ne_by_zenith", "payload"):
        assert c in COLUMNS


def test_empty_store_has_columns(tmp_path):
    df = store.read_store(tmp_path / "nothing")
    assert df.empty and list(df.columns) == list(COLUMNS)


def test_temp_file_of_killed_writer_is_invisible(tmp_path):
    store.write_row(tmp_path, _row("a1"))
    d = tmp_path / "runs" / "s"
    # what a writer killed between write and rename leaves behind: a partial hidden file
    (d / ".b2.parquet.tmp.123.abcd").write_bytes(b"PAR1 partial")
    with warnings.catch_warnings():
        warnings.simplefilter("error")           # no warning either: temp files are ignored
        df = store.read_store(tmp_path)
    assert list(df["run_id"]) == ["a1"]
    assert store.stored_status(tmp_path, "s") == {"a1": "ok"}


def test_corrupt_and_foreign_files_skipped_with_warning(tmp_path):
    store.write_row(tmp_path, _row("a1"))
    d = tmp_path / "runs" / "s"
    (d / "corrupt.parquet").write_bytes(b"not parquet at all")
    pq.write_table(pa.table({"x": [1, 2]}), d / "foreign.parquet")
    with pytest.warns(store.StoreWarning) as rec:
        df = store.read_store(tmp_path)
    msgs = " ".join(str(w.message) for w in rec)
    assert "corrupt.parquet" in msgs and "foreign.parquet" in msgs
    assert list(df["run_id"]) == ["a1"]


def test_older_schema_file_is_conformed(tmp_path):
    d = tmp_path / "runs" / "s"
    d.mkdir(parents=True)
    t = pa.table({"run_id": ["old"], "sweep": ["s"], "status": ["ok"],
                  "schema_version": pa.array([0], pa.int32()),
                  "utc": pa.array([pd.Timestamp("2026-01-01", tz="UTC")], pa.timestamp("us", tz="UTC")),
                  "ne_mean": [2.5]}).replace_schema_metadata({META_KEY: b"0"})
    pq.write_table(t, d / "old.parquet")
    df = store.read_store(tmp_path)
    assert df.loc[0, "ne_mean"] == 2.5 and pd.isna(df.loc[0, "ie_l2"])


def test_rerun_latest_wins_and_compaction_no_loss_no_dup(tmp_path):
    for i in range(5):
        store.write_row(tmp_path, _row(f"r{i}", utc=i))
    store.write_row(tmp_path, _row("x0", sweep="t", utc=0))
    assert store.compact(tmp_path) == {"s": 5, "t": 1}
    assert [p.name for p in (tmp_path / "runs" / "s").glob("*.parquet")] == ["compact.parquet"]
    # further runs: two new, one re-run of a compacted run (newer utc, different value)
    store.write_row(tmp_path, _row("r5", utc=10))
    store.write_row(tmp_path, _row("r6", utc=11))
    store.write_row(tmp_path, _row("r2", utc=12, ne_mean=9.0))
    df = store.read_store(tmp_path, sweep="s")
    assert sorted(df["run_id"]) == [f"r{i}" for i in range(7)]
    assert df.set_index("run_id").loc["r2", "ne_mean"] == 9.0
    assert store.compact(tmp_path, sweep="s") == {"s": 7}
    df2 = store.read_store(tmp_path)
    assert len(df2) == 8 and not df2.duplicated(["sweep", "run_id"]).any()
    assert df2.set_index("run_id").loc["r2", "ne_mean"] == 9.0
    assert pq.ParquetFile(tmp_path / "runs" / "s" / "compact.parquet").schema_arrow.metadata[META_KEY]
    assert store.compact(tmp_path) == {}          # nothing left to merge


def test_grid_expansion_union_scales_lists():
    exp = {"name": "e", "grids": [{"surface": ["semisphere", "penny"], "mask": ["None", "Th"]},
                                  {"surface": "spheres", "zenith": [30, 60], "mask": "Th"},
                                  {"surface": ["semisphere"], "mask": ["Th"]}],   # duplicate
           "fixed": {"model": "ts", "noise": 0.1},
           "scales": {"full": {"size": 512, "seed": [0]}, "ci": {"size": 48, "seed": [0, 1]}}}
    full = grid.expand(exp, "full")
    assert len(full) == 4 + 2                     # the duplicate Th/semisphere is kept once
    assert {p["size"] for p in full} == {512}
    ci = grid.expand(exp, "ci")
    assert len(ci) == 12 and {p["seed"] for p in ci} == {0, 1} and {p["size"] for p in ci} == {48}
    sph = [p for p in full if p["surface"] == "spheres"]
    assert sorted(p["lights"] for p in sph) == ["30x8", "60x8"]
    assert all(p["noise"] == 0.1 and p["model"] == "ts" for p in full)
    ids = [run.run_id(p) for p in full]
    assert len(set(ids)) == len(ids)
    assert ids == [run.run_id(p) for p in grid.expand(exp, "full")]       # stable
    with pytest.raises(PsbenchError, match="ci, full|full, ci"):
        grid.expand(exp, "huge")
    with pytest.raises(PsbenchError, match="unknown run parameter"):
        grid.expand({"name": "e", "grids": [{"colour": [1]}]})


def test_grid_lists_of_dicts_and_extras():
    exp = {"name": "e", "grids": [{"thresholds": [{"k_low": 0.0}, {"k_low": 0.1}]}],
           "fixed": {"extras": ["ne_by_zenith"]}}
    ps = grid.expand(exp)
    assert [p["thresholds"] for p in ps] == [{"k_low": 0.0}, {"k_low": 0.1}]
    assert all(p["extras"] == ["ne_by_zenith"] for p in ps)


def test_run_id_stable_and_sensitive(tmp_path):
    a = run.normalize({"mask": "Th", "noise": 0.1})
    b = run.normalize({"noise": 0.10, "mask": "Th", "seed": 0})
    c = run.normalize({"mask": "Th", "noise": 0.2})
    assert run.run_id(a) == run.run_id(b) != run.run_id(c)
    assert run.run_id(run.normalize({"zenith": 30, "count": 8})) == \
        run.run_id(run.normalize({"lights": "30x8"}))
    # render options do not change the identity of a data run
    d1 = run.normalize({"data": str(tmp_path), "noise": 0.1})
    d2 = run.normalize({"data": str(tmp_path), "noise": 0.3, "size": 9})
    assert run.run_id(d1) == run.run_id(d2) and d1["lights"] is None
    with pytest.raises(PsbenchError, match="valid"):
        run.normalize({"colour": 1})



def test_a_moved_store_keeps_its_run_ids(tmp_path):
    """A path inside the store (a surface file an experiment makes there, a capture folder)
    is hashed relative to it: moving or copying the store neither re-runs its runs nor
    hides them from the report; a path outside it still counts as given."""
    import shutil

    import numpy as np

    def runs(root):
        return [run.normalize({"surface": str(root / "made" / "z.npy"), "mask": m,
                               "lights": "45x8"}) for m in ("None", "Th")]

    old = tmp_path / "old"
    (old / "made").mkdir(parents=True)
    yy, xx = np.mgrid[-1:1:24j, -1:1:24j]
    np.save(old / "made" / "z.npy", 4 * np.exp(-3 * (xx ** 2 + yy ** 2)))
    assert shards.execute_runs(runs(old), root=old, sweep="s", jobs=1)["ok"] == 2
    new = tmp_path / "elsewhere" / "new"
    new.parent.mkdir()
    shutil.move(old, new)
    assert shards.execute_runs(runs(new), root=new, sweep="s", jobs=1)["todo"] == 0
    ids = sorted(store.read_store(new)["run_id"])
    assert ids == sorted(run.run_id(p, root=new) for p in runs(new))
    # hashed relative to the store only when it is inside it
    assert run.run_id(runs(new)[0], root=tmp_path / "other") != run.run_id(runs(new)[0], root=new)


def _noop_runs(n, fail=()):
    return [run.normalize({"kind": "noop", "seed": i,
                           "args": {"fail": "boom"} if i in fail else {}}) for i in range(n)]


def test_execute_runs_joblib_failing_run_does_not_stop(tmp_path):
    runs = _noop_runs(6, fail={2})
    out = shards.execute_runs(runs, root=tmp_path, sweep="sw", jobs=2)
    assert (out["ok"], out["failed"], out["skipped"]) == (5, 1, 0)
    df = store.read_store(tmp_path)
    assert len(df) == 6
    bad = df[df["status"] == "failed"].iloc[0]
    assert "RuntimeError: boom" in bad["error"] and "boom" in bad["traceback"]
    # re-run: nothing to do; retry_failed retries only the failed one; rerun redoes all
    assert shards.execute_runs(runs, root=tmp_path, sweep="sw", jobs=1)["todo"] == 0
    assert shards.execute_runs(runs, root=tmp_path, sweep="sw", jobs=1, retry_failed=True)["todo"] == 1
    assert shards.execute_runs(runs, root=tmp_path, sweep="sw", jobs=1, rerun=True)["todo"] == 6
    assert len(store.read_store(tmp_path)) == 6


def test_chunks_group_scenes():
    ps = [run.normalize({"surface": s, "mask": m, "size": 32})
          for s in ("semisphere", "penny") for m in ("None", "Th", "Sh")]
    chunks = shards.make_chunks(ps, workers=1, target=1)
    assert len(chunks) == 2 and all(len({run.scene_key(p) for p in c}) == 1 for c in chunks)
    sh = shards.split_shards(shards.make_chunks(_noop_runs(10), workers=1, target=1), 3)
    assert sorted(len(c) for s in sh for c in s) == [1] * 10 and len(sh) == 3


def test_analysis_runs_with_one_scene_spread_over_workers_in_order():
    # the runs of one analysis differ only in args (e.g. experiment breechface, where
    # each takes half an hour): they must not form one chunk that one worker runs alone
    ps = [run.normalize({"kind": "analysis", "analysis": "breechface",
                         "args": {"part": "method", "label": lab}})
          for lab in ("None", "Th-Hi-Re-Sh", "recipe", "robust")]
    assert len({run.scene_key(p) for p in ps}) == 1
    chunks = shards.make_chunks(ps, workers=2, target=1)
    assert [len(c) for c in chunks] == [1, 1, 1, 1]
    assert [c[0]["args"]["label"] for c in chunks] == ["None", "Th-Hi-Re-Sh", "recipe",
                                                       "robust"]


@pytest.mark.parametrize("launcher", ["submitit_debug", "submitit_local"])
def test_sharded_execution_two_shards(tmp_path, launcher):
    runs = _noop_runs(5, fail={4})
    out = shards.execute_runs(runs, root=tmp_path / "res", sweep="shard", launcher=launcher,
                              shards=2, submitit={"folder": str(tmp_path / "sub")})
    assert (out["ok"], out["failed"]) == (4, 1)
    df = store.read_store(tmp_path / "res")
    assert sorted(df["run_id"]) == sorted(run.run_id(p) for p in runs)
    assert shards.execute_runs(runs, root=tmp_path / "res", sweep="shard", launcher=launcher,
                               shards=2, submitit={"folder": str(tmp_path / "sub")})["todo"] == 0


def test_row_provenance(tmp_path):
    row = run.execute(run.normalize({"kind": "cond", "lights": "45x8"}), sweep="p")
    assert row["status"] == "ok" and row["cond"] == pytest.approx(2 ** 0.5)
    assert row["zenith"] == 45.0 and row["count"] == 8 and row["n_images"] == 8
    libs = json.loads(row["libs"])
    assert "numpy" in libs and row["host"] and row["psbench_version"]
    assert row["peak_mem_mb"] and row["peak_mem_mb"] > 0
    store.write_row(tmp_path, {k: v for k, v in row.items() if not k.startswith("_")})
    assert json.loads(store.read_store(tmp_path).loc[0, "config"])["lights"] == "45x8"


def test_select_lights_nearest_subset():
    import numpy as np

    from psbench.lights import layout

    have = layout("30x16+60x16")
    imgs = np.arange(32, dtype=np.float32)[:, None, None] * np.ones((32, 2, 2), np.float32)
    sub, lay = run.select_lights(imgs, have, "30x4+60x4")
    assert sub.shape == (8, 2, 2) and lay.k == 8 and lay.n_rings == 2
    assert np.allclose(np.sort(lay.zenith), [30] * 4 + [60] * 4)
    assert len(set(sub[:, 0, 0].tolist())) == 8          # distinct images
    with pytest.raises(PsbenchError, match="needs 40"):
        run.select_lights(imgs, have, "45x40")


def test_solve_extras_and_analysis_rows():
    p = run.normalize({"surface": "semisphere", "size": 24, "mask": "None",
                       "extras": ["ne_by_zenith"], "noise": 0.0})
    row = run.execute(p, sweep="x")
    assert row["status"] == "ok", row.get("traceback")
    curve = json.loads(row["ne_by_zenith"])
    assert {"zenith", "ne", "count"} <= set(curve)
    for c in ("ne_mean", "ne_lt20", "ie_l1", "ie_l2", "ie_linf", "ie_rel", "qf_total", "t_render"):
        assert row[c] is not None, c
    a = run.normalize({"kind": "analysis", "analysis": "ie_decomposition", "surface": "sombrero2",
                       "zenith": 45, "count": 8, "size": 24, "noise": 0.0})
    row = run.execute(a, sweep="x")
    assert row["status"] == "ok", row.get("traceback")
    payload = pd.DataFrame(json.loads(row["payload"]))
    assert set(payload["source_zenith"]) == {45.0}          # the run's zenith is passed
    bad = run.execute(run.normalize({"kind": "analysis", "analysis": "nope"}), sweep="x")
    assert bad["status"] == "failed" and "ie_decomposition" in bad["error"]


def test_results_cli_compact_ls_verify(tmp_path, capsys):
    from psbench.harness import cli

    for i in range(3):
        store.write_row(tmp_path, _row(f"r{i}", utc=i))
    assert cli.main(["ls", "--root", str(tmp_path)]) == 0
    assert "3" in capsys.readouterr().out
    assert cli.main(["compact", "--root", str(tmp_path)]) == 0
    assert "3 rows" in capsys.readouterr().out
    store.write_row(tmp_path, _row("r1", utc=9))            # re-run after compaction
    assert cli.main(["verify", "--root", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "stored 2 times" in out and "0 problem" in out
    (tmp_path / "runs" / "s" / "junk.parquet").write_bytes(b"junk")
    assert cli.main(["verify", "--root", str(tmp_path)]) == 1
    assert "junk.parquet" in capsys.readouterr().out
    with pytest.warns(store.StoreWarning, match="junk.parquet"):
        assert cli.main(["summary", "--root", str(tmp_path), "--by", "kind"]) == 0


def test_plus_prefix_accepted_for_existing_keys():
    from psbench.harness.app import _fix_argv

    assert _fix_argv(["+rerun=true", "++seed=1", "+experiment=t", "mask=Th",
                      "+thresholds.k_low=0.1", "+foo=1", "experiment=u"]) == \
        ["++rerun=true", "++seed=1", "++experiment=t", "mask=Th", "++thresholds.k_low=0.1", "+foo=1",
         "++experiment=u"]
