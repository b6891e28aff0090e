"""Byte flips in store files against the skip check.

For N random offsets in a per-run file and N in a compact file: flip one byte, ask
the skip check (:func:`psbench.harness.store.stored_status`) which runs are stored,
then read every run counted as stored back (:func:`read_run`, :func:`read_store`).
Counts runs counted as stored that do not read back and stored values that changed
silently (both must be 0), and how often the file was set aside.

Usage: python benchmarks/reliability_byteflip.py [N] [ROWS] (default 40 offsets, a
compact file of 738 rows).
"""
import math
import random
import shutil
import sys
import tempfile
import warnings
from pathlib import Path

from psbench.harness import store


def _rows(n, sweep):
    rnd = random.Random(5)
    return [dict(run_id=f"r{i:04d}", sweep=sweep, status="ok", kind="noop",
                 ne_mean=rnd.uniform(0, 30), ie_l2=rnd.uniform(0, 1), seed=i,
                 error=None, config='{"x": %d}' % i) for i in range(n)]


def _same(a, b):
    for k, v in a.items():
        w = b.get(k)
        if isinstance(v, float) and isinstance(w, float) and math.isnan(v) and math.isnan(w):
            continue
        if v != w:
            return False
    return True


def trial(kind, n_offsets, n_rows, seed=1):
    rnd = random.Random(seed)
    with tempfile.TemporaryDirectory() as d:
        root = Path(d)
        rows = _rows(1 if kind == "per-run" else n_rows, "s")
        store.write_rows(root, rows)
        if kind == "compact":
            store.compact(root)
        path = (store.run_path(root, "s", rows[0]["run_id"]) if kind == "per-run"
                else store.compact_path(root, "s"))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            want = {r["run_id"]: r for r in store.read_store(root).to_dict("records")}
        good = path.read_bytes()
        phantom = changed = aside = 0
        for _ in range(n_offsets):
            b = bytearray(good)
            b[rnd.randrange(len(b))] ^= rnd.randrange(1, 256)
            path.write_bytes(bytes(b))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                st = store.stored_status(root, "s")
                df = store.read_store(root)
            back = {r["run_id"]: r for r in df.to_dict("records")}
            for rid in st:
                if rid not in back:
                    phantom += 1
                elif not _same(want[rid], back[rid]):
                    changed += 1
            if not path.exists():
                aside += 1
            shutil.rmtree(root / "corrupt", ignore_errors=True)
            path.write_bytes(good)
        return phantom, changed, aside


def main(n=40, n_rows=738):
    bad = 0
    for kind in ("per-run", "compact"):
        phantom, changed, aside = trial(kind, n, n_rows)
        print(f"{kind} file ({1 if kind == 'per-run' else n_rows} rows), {n} byte flips: "
              f"{phantom} runs counted as stored that do not read back, {changed} silent value "
              f"changes, file set aside {aside}/{n} times")
        bad += phantom + changed
    return 1 if bad else 0


if __name__ == "__main__":
    a = [int(x) for x in sys.argv[1:]]
    sys.exit(main(*a))
