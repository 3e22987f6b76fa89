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


def test_unpack_into_a_folder_with_the_samples_keeps_them_and_refuses_unsafe_names(tmp_path):
    """Unpacked into the folder the caches came from (the real samples there), the
    placeholders must not truncate the samples; a name in a pack that is not a sample
    file name (``load_split`` reads only ``NNNNN.npz``) is refused before anything is
    written: a name like ``../x`` would truncate a file outside the data folder."""
    src, pack = tmp_path / "src", tmp_path / "pack"
    (src / "train").mkdir(parents=True)
    _cache(src / "cache_train_8.npz", 3)
    for i in range(3):
        (src / "train" / f"{i * 2:05d}.npz").write_bytes(b"a real sample")
    pack_cache.pack(str(src), ["train"], 8, str(pack))
    pack_cache.unpack(str(pack), str(src), check=str(src))
    assert [(src / "train" / f"{i * 2:05d}.npz").read_bytes() for i in range(3)] == [b"a real sample"] * 3

    bad = tmp_path / "bad"
    bad.mkdir()
    outside = tmp_path / "outside.npz"
    outside.write_bytes(b"keep me")
    rng = np.random.default_rng(0)
    np.savez(bad / "cache_train_8.npz", x=rng.random((1, 6, 8, 8)).astype(np.float16), n=1,
             meta=json.dumps([{}]), names=np.array(["../../outside.npz"]))
    pack_cache.pack(str(bad), ["train"], 8, str(tmp_path / "badpack"))
    with pytest.raises(SystemExit, match="outside.npz"):
        pack_cache.unpack(str(tmp_path / "badpack"), str(tmp_path / "dst"))
    assert outside.read_bytes() == b"keep me"
    assert not (tmp_path / "dst" / "cache_train_8.npz").exists()


def test_every_array_of_a_cache_travels(tmp_path):
    """A cache with an array the packer does not know by name (a later train.py's) comes
    back with it: the round trip is of the whole file, and ``--check`` would say so."""
    src, pack, dst = tmp_path / "src", tmp_path / "pack", tmp_path / "dst"
    src.mkdir()
    _cache(src / "cache_train_8.npz", 2)
    with np.load(src / "cache_train_8.npz") as z:
        arrays = {k: z[k] for k in z.files}
    np.savez(src / "cache_train_8.npz", **arrays, box=np.arange(8, dtype=np.int32).reshape(2, 4))
    pack_cache.pack(str(src), ["train"], 8, str(pack))
    pack_cache.unpack(str(pack), str(dst), check=str(src))
    with np.load(dst / "cache_train_8.npz") as b:
        assert b["box"].tolist() == [[0, 1, 2, 3], [4, 5, 6, 7]] and b["box"].dtype == np.int32


def test_unpack_over_the_checked_caches_still_compares_with_the_originals(tmp_path):
    # --data and --check the same folder: the check must read the caches before they are
    # overwritten (else it compares the unpacked arrays with themselves and always passes)
    src, pack = tmp_path / "src", tmp_path / "pack"
    src.mkdir()
    _cache(src / "cache_train_8.npz", 4, seed=3)
    pack_cache.pack(str(src), ["train"], 8, str(pack))
    _cache(src / "cache_train_8.npz", 4, seed=9)      # the caches changed after packing
    before = (src / "cache_train_8.npz").read_bytes()
    with pytest.raises(SystemExit, match="differs"):
        pack_cache.unpack(str(pack), str(src), check=str(src))
    assert (src / "cache_train_8.npz").read_bytes() == before       # and nothing written over them
