"""Store under faults: concurrent compactions, flipped bits, temporary files of dead
writers, and the one-line reads of pandas / pyarrow / duckdb (issue 11 S1, S6, S7;
issue 12 item 5)."""
import os
import random
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from psbench.harness import cli, store
from psbench.harness.params import normalize
from psbench.harness.run import execute


def _row(rid, sweep="s", **kw):
    r = dict(run_id=rid, sweep=sweep, status="ok", kind="noop", ne_mean=1.0)
    r.update(kw)
    return r


_WRITER = """
import sys
from psbench.harness.grid import expand
from psbench.harness.shards import execute_runs
runs = expand({"name": "conc", "grids": [{"kind": "noop", "seed": list(range(90)),
               "args": {"sleep": 0.01}}]})
out = execute_runs(runs, root=sys.argv[1], sweep="conc", experiment="conc", jobs=1)
assert out["ok"] == 90, out
"""

_COMPACTOR = """
import sys, time, pathlib
from psbench.harness import store
stop = pathlib.Path(sys.argv[2])
while not stop.exists():
    store.compact(sys.argv[1], sweep="conc")
"""


def test_concurrent_compactions_lose_no_row(tmp_path):
    """S1: an experiment writes while two compactions loop; a final compact holds
    exactly the grid's rows."""
    root, stop = tmp_path / "res", tmp_path / "stop"
    env = dict(os.environ)
    comps = [subprocess.Popen([sys.executable, "-c", _COMPACTOR, str(root), str(stop)], env=env)
             for _ in range(2)]
    try:
        w = subprocess.run([sys.executable, "-c", _WRITER, str(root)], env=env,
                           capture_output=True, text=True, timeout=300)
        assert w.returncode == 0, w.stderr
    finally:
        stop.write_text("")
        for c in comps:
            c.wait(timeout=120)
    assert all(c.returncode == 0 for c in comps)
    assert store.compact(root) in ({"conc": 90}, {})
    files = [p.name for p in (root / "runs" / "conc").iterdir() if not p.name.startswith(".")]
    assert files == ["compact.parquet"]
    df = store.read_store(root)
    assert len(df) == 90 and df["run_id"].is_unique and set(df["status"]) == {"ok"}
    assert not store.temp_files(root)


def test_flipped_bits_are_detected_never_silent(tmp_path):
    """S6: single-bit flips anywhere in a run file are either reported by ``verify``
    (and the file skipped by readers) or leave every stored value unchanged."""
    row = execute(normalize(dict(size=16, surface="semisphere")), sweep="s")
    assert row.pop("_exc", None) is None and row["status"] == "ok"
    path = store.write_row(tmp_path, row)
    want = store.read_store(tmp_path).iloc[0]
    data = path.read_bytes()
    rnd = random.Random(11)
    detected = 0
    for _ in range(120):
        b = bytearray(data)
        b[rnd.randrange(len(b))] ^= 1 << rnd.randrange(8)
        path.write_bytes(bytes(b))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            df = store.read_store(tmp_path)
            bad = cli.main(["verify", "--root", str(tmp_path)]) != 0
        if df.empty:
            assert bad
            detected += 1
            continue
        got = df.iloc[0]
        for c in df.columns:                     # an undetected flip changed nothing
            a, b_ = want[c], got[c]
            assert (pd.isna(a) and pd.isna(b_)) or a == b_, c
    assert detected > 40                         # most flips land in checksummed pages


def test_verify_names_a_flipped_data_byte(tmp_path, capsys):
    import pyarrow.parquet as pq

    store.write_row(tmp_path, _row("a1"))
    p = store.write_row(tmp_path, _row("a2", ne_mean=1.2345))
    assert cli.main(["verify", "--root", str(tmp_path)]) == 0
    meta = pq.ParquetFile(p).metadata.row_group(0)
    col = next(meta.column(i) for i in range(meta.num_columns)
               if meta.column(i).path_in_schema == "ne_mean")
    b = bytearray(p.read_bytes())
    b[col.data_page_offset + col.total_compressed_size - 1] ^= 0x10   # the value's page
    p.write_bytes(bytes(b))
    capsys.readouterr()
    assert cli.main(["verify", "--root", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert "a2.parquet" in out and "1 problem(s)" in out


def test_results_cli_names_a_damaged_file_in_one_line(tmp_path):
    """``psbench-results`` prints a store warning as one ``psbench: warning:`` line on
    stderr (not Python's file:line and source line), like the other commands."""
    import pyarrow.parquet as pq

    p = store.write_row(tmp_path, _row("a1"))
    meta = pq.ParquetFile(p).metadata.row_group(0)
    col = next(meta.column(i) for i in range(meta.num_columns)
               if meta.column(i).path_in_schema == "ne_mean")
    b = bytearray(p.read_bytes())
    b[col.data_page_offset + col.total_compressed_size - 1] ^= 0x10
    p.write_bytes(bytes(b))
    exe = Path(sys.executable).parent / "psbench-results"
    r = subprocess.run([str(exe), "ls", "--root", str(tmp_path)], capture_output=True,
                       text=True, timeout=240)
    assert r.returncode == 0 and "no runs stored" in r.stdout, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("psbench: warning: ") and p.name in lines[0]


def test_dead_writers_temporary_files(tmp_path, capsys):
    """S7: a temporary file of a killed writer is reported by verify and removed by
    compact; one of a live writer is left alone."""
    store.write_row(tmp_path, _row("a1"))
    d = tmp_path / "runs" / "s"
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True).stdout.strip()
    from psbench._shared.files import HOST

    old = d / f".b2.parquet.tmp.{dead}.abcd.{HOST}"
    old.write_bytes(b"PAR1 partial")
    live = d / f".b3.parquet.tmp.{os.getpid()}.abcd.{HOST}"
    live.write_bytes(b"PAR1 partial")
    legacy = tmp_path / "compact"
    legacy.mkdir()
    stale = legacy / f".s.parquet.tmp.{dead}.beef.{HOST}"
    stale.write_bytes(b"PAR1")
    past = time.time() - 10
    for p in (old, live, stale):
        os.utime(p, (past, past))
    assert cli.main(["verify", "--root", str(tmp_path)]) == 1
    out = capsys.readouterr().out
    assert old.name in out and stale.name in out and live.name not in out
    assert "1 temporary file(s) of writers that may still be running" in out
    store.compact(tmp_path)
    assert not old.exists() and not stale.exists() and live.exists()
    live.unlink()
    assert cli.main(["verify", "--root", str(tmp_path)]) == 0


def test_compaction_keeps_a_rerun_written_meanwhile(tmp_path):
    """A per-run file replaced while it was being compacted is kept (its new row is
    not in the compact file yet)."""
    p = store.write_row(tmp_path, _row("r1", ne_mean=1.0))
    sig = store._sig(p.stat())
    store.write_row(tmp_path, _row("r1", ne_mean=2.0))      # replaced after "reading"
    assert not store._remove_merged(p, sig)
    assert p.exists()
    assert store.read_store(tmp_path).loc[0, "ne_mean"] == 2.0


def test_one_line_readers_compacted_or_not(tmp_path):
    """Issue 12 item 5: pandas, pyarrow datasets and duckdb read the whole store."""
    import pyarrow.dataset as ds

    for i in range(4):
        store.write_row(tmp_path, _row(f"r{i}", ne_mean=float(i)))
    store.write_row(tmp_path, _row("x", sweep="t"))
    runs = str(tmp_path / "runs")

    def counts():
        out = [len(pd.read_parquet(runs)), ds.dataset(runs).count_rows()]
        duckdb = pytest.importorskip("duckdb")
        out.append(duckdb.sql(f"SELECT count(*) FROM '{runs}/*/*.parquet'").fetchall()[0][0])
        return out

    assert counts() == [5, 5, 5]
    store.compact(tmp_path)
    assert counts() == [5, 5, 5]
    df = pd.read_parquet(runs)
    assert sorted(df["run_id"]) == ["r0", "r1", "r2", "r3", "x"]
    assert np.isclose(df.loc[df["run_id"] == "r3", "ne_mean"].iloc[0], 3.0)


def test_store_of_the_previous_layout_is_read_and_moved(tmp_path):
    import pyarrow.parquet as pq

    from psbench.harness.schema import row_table

    (tmp_path / "compact").mkdir()
    pq.write_table(row_table([_row("old", utc=None) | {"schema_version": 1,
                                                        "utc": pd.Timestamp("2026-01-01",
                                                                            tz="UTC")}]),
                   tmp_path / "compact" / "s.parquet")
    store.write_row(tmp_path, _row("new"))
    assert sorted(store.read_store(tmp_path)["run_id"]) == ["new", "old"]
    assert store.compact(tmp_path) == {"s": 2}
    assert not (tmp_path / "compact" / "s.parquet").exists()
    assert sorted(store.read_store(tmp_path)["run_id"]) == ["new", "old"]


def _flip_page(path, column):
    import pyarrow.parquet as pq

    meta = pq.ParquetFile(path).metadata.row_group(0)
    col = next(meta.column(i) for i in range(meta.num_columns)
               if meta.column(i).path_in_schema == column)
    b = bytearray(path.read_bytes())
    b[col.data_page_offset + col.total_compressed_size - 1] ^= 0x10
    path.write_bytes(bytes(b))


@pytest.mark.parametrize("compacted", [False, True])
def test_a_damaged_page_is_not_stored_and_is_set_aside(tmp_path, compacted):
    """The skip check reads what read_store reads: a flipped byte in a column it does
    not use still makes the run unstored, and the file is moved aside, not deleted."""
    store.write_rows(tmp_path, [_row(f"a{i}", ne_mean=float(i), ie_l2=0.5) for i in range(5)])
    if compacted:
        store.compact(tmp_path)
    p = store.compact_path(tmp_path, "s") if compacted else store.run_path(tmp_path, "s", "a3")
    _flip_page(p, "ie_l2" if compacted else "ne_mean")
    with pytest.warns(store.StoreWarning, match=f"{p.name}.*moved aside"):
        st = store.stored_status(tmp_path, "s")
    assert sorted(st) == ([] if compacted else ["a0", "a1", "a2", "a4"])
    assert not p.exists()
    kept = list((tmp_path / "corrupt" / "s").iterdir())
    assert len(kept) == 1 and kept[0].name.startswith(p.name)
    assert set(store.read_store(tmp_path)["run_id"]) == set(st)


def test_resume_recomputes_a_damaged_run(tmp_path):
    """Issue scenario: `psbench size=.. mask=Th outputs=none`, one byte flipped in the
    ne_mean page, the same command again computes the run instead of skipping it."""
    cmd = [str(Path(sys.executable).parent / "psbench"), "size=16", "mask=Th", "outputs=none",
           "results_dir=res"]
    env = {k: v for k, v in os.environ.items() if k != "PSBENCH_RESULTS"}
    first = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert first.returncode == 0, first.stderr
    (p,) = (tmp_path / "res" / "runs" / "adhoc").glob("*.parquet")
    _flip_page(p, "ne_mean")
    again = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert again.returncode == 0, again.stderr
    assert "skipped" not in again.stdout and "stored" in again.stdout
    assert "moved aside" in again.stderr and p.name in again.stderr
    assert len(store.read_store(tmp_path / "res")) == 1


def test_byte_flips_reduced():
    """Reduced version of benchmarks/reliability_byteflip.py (40 + 40 flips, 738 rows)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    try:
        import reliability_byteflip as bf
    finally:
        sys.path.pop(0)
    for kind in ("per-run", "compact"):
        phantom, changed, aside = bf.trial(kind, 8, 20, seed=3)
        assert (phantom, changed) == (0, 0)
        assert aside > 0
