"""The breech-face study's cache: maps and comparisons kept, a stopped study resumed."""
from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from psbench import PsbenchError
from psbench.forensic import breechface as bf
from psbench.forensic.study_cache import StudyCache, digest


def _fields(n, size=96, seed=0):
    """n band-limited random fields on a disc; 0 and 1, 2 and 3 ... share a field."""
    rng = np.random.default_rng(seed)
    import scipy.ndimage as ndi

    yy, xx = np.mgrid[:size, :size] - (size - 1) / 2
    disc = np.hypot(yy, xx) < 0.45 * size
    base = [ndi.gaussian_filter(rng.normal(size=(size, size)), 2) for _ in range(n // 2 + 1)]
    maps, valid, guns = {}, {}, {}
    for i in range(n):
        z = base[i // 2] + 0.3 * ndi.gaussian_filter(rng.normal(size=(size, size)), 2)
        maps[f"s{i}"] = np.where(disc, z, 0).astype(np.float32)
        valid[f"s{i}"] = disc
        guns[f"s{i}"] = str(i // 2)
    return maps, valid, guns


OPTS = {"cells": (4, 4), "angles": (-3, 0, 3), "translation_tol": 6.0}


def test_digest_tells_arrays_and_values_apart():
    a = np.arange(6, dtype=np.float32)
    assert digest(a, 1) == digest(a.copy(), 1)
    assert digest(a, 1) != digest(a, 2)
    assert digest(a) != digest(a.reshape(2, 3))
    assert digest(a) != digest(a.astype(np.float64))


def test_maps_are_computed_once_and_read_back_exactly(tmp_path):
    calls = []
    z = np.random.default_rng(1).normal(size=(8, 9)).astype(np.float32)

    def compute():
        calls.append(1)
        return [z, 2 * z], [[{"a": 1}], [{"a": 2}]]

    cache = StudyCache(tmp_path)
    first = cache.maps(["k-p", "k-b"], compute)
    again = cache.maps(["k-p", "k-b"], compute)
    assert len(calls) == 1
    assert all(np.array_equal(x, y) for x, y in zip(first[0], again[0]))
    assert again[1] == [[{"a": 1}], [{"a": 2}]]
    # one key missing: everything is computed again (one solve gives every integrator)
    (tmp_path / "maps" / "k-b.npz").unlink()
    cache.maps(["k-p", "k-b"], compute)
    assert len(calls) == 2
    # no cache folder: always computed, nothing written
    StudyCache(None).maps(["k-p"], compute)
    assert len(calls) == 3


def test_scores_with_a_cache_equal_those_without_and_resume(tmp_path):
    maps, valid, guns = _fields(4)
    plain = bf.score_pairs(maps, valid, guns, pixel_size=6.25, **OPTS)
    assert len(plain) == 6 and plain.same_gun.sum() == 2
    cols = ["a", "b", "same_gun", "count", "cells", "ccf", "dx", "dy", "theta"]
    cached = bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=tmp_path, **OPTS)
    pd.testing.assert_frame_equal(plain[cols], cached[cols])
    files = sorted((tmp_path / "pairs").rglob("*.json"))
    assert len(files) == 3                          # one per reference with targets
    # a study stopped after its first reference: drop the others' files, and poison the
    # first's stored rows, so that a resumed study shows it reads them and computes the rest
    for f in files:
        rows = json.loads(f.read_text())
        if len(rows) == 3:
            for r in rows.values():
                r["count"] = -7
            f.write_text(json.dumps(rows))
        else:
            f.unlink()
    seen = []
    again = bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=tmp_path,
                           progress=lambda d, t: seen.append((d, t)), **OPTS)
    assert (again.loc[again.a == "s0", "count"] == -7).all()
    pd.testing.assert_frame_equal(plain.loc[plain.a != "s0", cols],
                                  again.loc[again.a != "s0", cols])
    assert seen == [(3, 6), (5, 6), (6, 6)]


def test_other_options_or_maps_are_not_taken_from_the_cache(tmp_path):
    maps, valid, guns = _fields(3)
    bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=tmp_path, **OPTS)
    other = bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=tmp_path,
                           **{**OPTS, "min_ccf": 0.9})
    direct = bf.score_pairs(maps, valid, guns, pixel_size=6.25, **{**OPTS, "min_ccf": 0.9})
    assert other["count"].tolist() == direct["count"].tolist()
    maps["s1"] = maps["s1"][::-1].copy()
    flipped = bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=tmp_path, **OPTS)
    assert flipped["count"].tolist() == bf.score_pairs(maps, valid, guns, pixel_size=6.25,
                                                       **OPTS)["count"].tolist()


def test_worker_processes_give_the_same_scores(tmp_path):
    maps, valid, guns = _fields(4)
    one = bf.score_pairs(maps, valid, guns, pixel_size=6.25, **OPTS)
    seen = []
    two = bf.score_pairs(maps, valid, guns, pixel_size=6.25, jobs=2, cache=tmp_path,
                         progress=lambda d, t: seen.append(d), **OPTS)
    cols = ["a", "b", "same_gun", "count", "cells", "ccf", "dx", "dy", "theta"]
    pd.testing.assert_frame_equal(one[cols], two[cols])
    assert sorted(seen)[-1] == 6 and len(seen) == 3


@pytest.mark.parametrize("jobs", [0, -3, 1.5, "2"])
def test_bad_jobs_is_named(jobs):
    maps, valid, guns = _fields(2)
    with pytest.raises(PsbenchError, match="jobs"):
        bf.score_pairs(maps, valid, guns, pixel_size=6.25, jobs=jobs, **OPTS)


def test_a_pairs_table_carries_comparisons_to_another_cache_folder(tmp_path):
    maps, valid, guns = _fields(4)
    cols = ["a", "b", "same_gun", "count", "cells", "ccf", "dx", "dy", "theta"]
    pairs = tmp_path / "pairs.parquet"
    first = StudyCache(tmp_path / "one", pairs)
    plain = bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=first, **OPTS)
    assert first.export() == 6
    assert first.export() == 6                     # merging again adds no duplicates
    table = pd.read_parquet(pairs)
    assert len(table) == 6 and table["count"].tolist() != [-7] * 6
    # poison the table: a fresh folder (another checkout) must read it, not compare again
    table["count"] = -7
    table.to_parquet(pairs, index=False)
    fresh = StudyCache(tmp_path / "two", pairs)
    again = bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=fresh, **OPTS)
    assert (again["count"] == -7).all()
    pd.testing.assert_frame_equal(plain[cols[:4]].assign(count=-7), again[cols[:4]])
    # a map that differs by one value misses the table: its pairs are compared afresh
    maps["s3"] = maps["s3"].copy()
    maps["s3"][48, 48] += 1e-3
    changed = bf.score_pairs(maps, valid, guns, pixel_size=6.25,
                             cache=StudyCache(tmp_path / "three", pairs), **OPTS)
    touched = (changed.a == "s3") | (changed.b == "s3")
    assert (changed.loc[~touched, "count"] == -7).all()
    assert (changed.loc[touched, "count"] >= 0).all()
    # a table without a folder is read-only: export does nothing
    assert StudyCache(None, pairs).export() == 0


def test_a_bad_pairs_table_is_named(tmp_path):
    maps, valid, guns = _fields(2)
    bad = tmp_path / "pairs.parquet"
    bad.write_text("not parquet")
    with pytest.raises(PsbenchError, match="pairs.parquet: not a readable Parquet"):
        bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=StudyCache(None, bad),
                       **OPTS)
    pd.DataFrame({"options": ["x"]}).to_parquet(bad)
    with pytest.raises(PsbenchError, match="missing columns"):
        bf.score_pairs(maps, valid, guns, pixel_size=6.25, cache=StudyCache(None, bad),
                       **OPTS)
