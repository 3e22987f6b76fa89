"""lab/height/pack_cache.py: the training caches travel packed and come back bit for bit."""
import json
import os

import numpy as np
import pytest

from pixgraph_lab.height import pack_cache


def _cache(path, n, names=True, seed=0):
    rng = np.random.default_rng(seed)
    arrays = {"x": rng.normal(size=(n, 6, 8, 8)).astype(np.float16),
              "t": rng.random((n, 8, 8)).astype(np.float16),
              "w": (rng.random((n, 8, 8)) > 0.5).astype(np.float16),
              "bh": rng.random(n).astype(np.float32), "n": n,
              "meta": json.dumps([{"mesh": f"m{i}", "h": float(i) / 3} for i in range(n)])}
    if names:
        arrays["names"] = np.array([f"{i * 2:05d}.npz" for i in range(n)])
    np.savez(path, **arrays)


def test_pack_round_trip_is_bit_exact(tmp_path):
    src, pack, dst = tmp_path / "src", tmp_path / "pack", tmp_path / "dst"
    src.mkdir()
    _cache(src / "cache_train_8.npz", 5)
    _cache(src / "cache_val_8.npz", 3, names=False, seed=1)
    pack_cache.pack(str(src), ["train", "val"], 8, str(pack))
    pack_cache.unpack(str(pack), str(dst), check=str(src))
    for split in ("train", "val"):
        with np.load(src / f"cache_{split}_8.npz") as a, np.load(dst / f"cache_{split}_8.npz") as b:
            assert sorted(a.files) == sorted(b.files)
            for k in a.files:
                assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
                assert a[k].tobytes() == b[k].tobytes(), k
    # the placeholders load_split globs: the cache's own names, or 00000.npz ... when it has none
    assert sorted(os.listdir(dst / "train")) == [f"{i * 2:05d}.npz" for i in range(5)]
    assert sorted(os.listdir(dst / "val")) == [f"{i:05d}.npz" for i in range(3)]


def test_unpack_check_finds_a_changed_array(tmp_path):
    src, pack = tmp_path / "src", tmp_path / "pack"
    src.mkdir()
    _cache(src / "cache_train_8.npz", 4)
    pack_cache.pack(str(src), ["train"], 8, str(pack))
    _cache(src / "cache_train_8.npz", 4, seed=7)      # the original changed after packing
    with pytest.raises(SystemExit, match="array x differs"):
        pack_cache.unpack(str(pack), str(tmp_path / "dst"), check=str(src))
