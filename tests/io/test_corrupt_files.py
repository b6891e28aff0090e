"""Corrupt DiLiGenT files: one error naming the file and what was expected."""
import random

import numpy as np
import pytest
import scipy.io as sio

from psbench._shared.checks import PsbenchError
from psbench.io import read_dataset, write_dataset


@pytest.fixture
def folder(tmp_path):
    rng = np.random.default_rng(0)
    lights = np.array([[0, 0, 1], [0.3, 0, 0.95], [0, 0.3, 0.95]], float)
    lights /= np.linalg.norm(lights, axis=1, keepdims=True)
    d = tmp_path / "obj"
    write_dataset(d, rng.uniform(0.1, 0.9, (3, 8, 8)), lights)
    n = np.zeros((8, 8, 3), np.float32)
    n[..., 2] = 1
    sio.savemat(d / "Normal_gt.mat", {"Normal_gt": n})
    read_dataset(d)                     # intact: reads
    return d


def _damage(p, how, seed):
    data = bytearray(p.read_bytes())
    if how == "garbage":
        data = bytearray(b"this is not a MATLAB file" * 8)
    elif how == "truncated":
        data = data[: len(data) // 2]
    else:
        rnd = random.Random(seed)
        for _ in range(8):
            data[rnd.randrange(128, len(data))] ^= 0xFF
    p.write_bytes(bytes(data))


@pytest.mark.parametrize("how", ["garbage", "truncated", "flipped"])
def test_corrupt_normal_gt_is_named(folder, how):
    p = folder / "Normal_gt.mat"
    _damage(p, how, 1)
    try:
        read_dataset(folder)
    except PsbenchError as e:
        msg = str(e)
        assert "\n" not in msg and str(p) in msg, msg
        assert "expected" in msg or "no key 'Normal_gt'" in msg, msg
    # (a flip that leaves the file decodable, with the right shape, reads as normals)


def test_corrupt_normals_npy_is_named(folder):
    (folder / "normals.npy").write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(PsbenchError, match=r"normals\.npy.*expected"):
        read_dataset(folder)


def test_write_dataset_warns_when_it_clips(tmp_path):
    from psbench.io import PsbenchWarning

    imgs = np.full((3, 4, 4), 0.5)
    imgs[0, 0, 0] = 5.0
    lights = np.array([[0, 0, 1.0], [0.6, 0, 0.8], [0, 0.6, 0.8]])
    with pytest.warns(PsbenchWarning, match=r"1 image values outside \[0, 1\].*max 5") as rec:
        write_dataset(tmp_path / "d", imgs, lights)
    assert rec[0].filename == __file__                  # points at the caller's line
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_dataset(tmp_path / "e", np.full((3, 4, 4), 0.5), lights)
