"""train.load_split's crop cache: reused when the snapshot is unchanged, grown (the
crops already made kept, by file name) when samples were added."""
import json

import numpy as np
import pytest

pytest.importorskip("torch")

from pixgraph_lab.height import train  # noqa: E402


def write_sample(path, k):
    rng = np.random.default_rng(k)
    m = np.zeros((40, 40), bool)
    m[5 + k:35, 10:30 - k] = True
    h = np.where(m, 35.0 - (np.arange(40)[:, None] + 0.5), 0.0)
    np.savez(path, rgb=rng.integers(0, 255, (40, 40, 3), dtype=np.uint8),
             alpha=(m * 255).astype(np.uint8), height=h.astype(np.float16), mask=m,
             meta=np.array(json.dumps({"index": k})))


def test_cache_grows_with_the_snapshot(tmp_path, monkeypatch):
    d = tmp_path / "train"
    d.mkdir()
    for k in (0, 2):
        write_sample(d / f"{k:05d}.npz", k)
    first = train.load_split(str(tmp_path), "train", 16)
    assert [m["index"] for m in first["meta"]] == [0, 2]
    write_sample(d / "00001.npz", 1)                  # a sample added in between, sorted before 2
    from pixgraph_nodes.ops import learned_height as lh
    calls = []
    real = lh.prepare
    monkeypatch.setattr(lh, "prepare", lambda *a, **k: calls.append(1) or real(*a, **k))
    grown = train.load_split(str(tmp_path), "train", 16)
    assert len(calls) == 1                            # only the new file was cropped
    assert [m["index"] for m in grown["meta"]] == [0, 1, 2]
    np.testing.assert_array_equal(grown["x"][[0, 2]], first["x"])
    np.testing.assert_array_equal(grown["t"][[0, 2]], first["t"])
    fresh_dir = tmp_path / "fresh"
    (fresh_dir / "train").mkdir(parents=True)
    for k in (0, 1, 2):
        write_sample(fresh_dir / "train" / f"{k:05d}.npz", k)
    monkeypatch.setattr(lh, "prepare", real)
    fresh = train.load_split(str(fresh_dir), "train", 16)
    np.testing.assert_array_equal(grown["x"], fresh["x"])      # same as cropping all from scratch
    np.testing.assert_array_equal(grown["bh"], fresh["bh"])
    calls.clear()
    monkeypatch.setattr(lh, "prepare", lambda *a, **k: calls.append(1) or real(*a, **k))
    again = train.load_split(str(tmp_path), "train", 16)        # unchanged: read from the cache
    np.testing.assert_array_equal(again["x"], grown["x"])
    assert calls == []                                          # nothing cropped again


def test_training_batches_are_the_host_indexed_crops(tmp_path, monkeypatch):
    """train.main holds the crops on the training device and gathers each step's batch
    there (eighth session): the batches handed to ``augment`` are exactly the float32
    crops that indexing the host arrays with the same seeded rng gives, step after step,
    across a resume (the rng state is restored from ``last.pt``)."""
    import torch
    for split, ks in (("train", (0, 1, 2, 3, 4)), ("val", (5,))):
        (tmp_path / split).mkdir()
        for k in ks:
            write_sample(tmp_path / split / f"{k:05d}.npz", k)
    seen = []
    real = train.augment

    def recording(x, t, w, gen, *rest):
        seen.append(tuple(v.detach().cpu().clone() for v in (x, t, w)))
        return real(x, t, w, gen, *rest)

    monkeypatch.setattr(train, "augment", recording)
    args = ["--data", str(tmp_path), "--out", str(tmp_path / "run"), "--size", "16", "--base", "4",
            "--levels", "2", "--batch", "3", "--steps", "4", "--val-every", "2", "--seed", "7"]
    assert train.main(args + ["--minutes", "0"]) == 0     # one step, then a checkpoint
    assert train.main(args) == 0                          # resumed: steps 2-4
    host = train.load_split(str(tmp_path), "train", 16)
    rng = np.random.default_rng(7)
    assert len(seen) == 4
    for x, t, w in seen:
        idx = rng.integers(5, size=3)
        for got, k in ((x, "x"), (t, "t"), (w, "w")):
            assert got.dtype == torch.float32
            np.testing.assert_array_equal(got.numpy(), host[k][idx].astype(np.float32))
    # the five crops differ, so a batch drawn with other indices would not match
    assert len({host["x"][i].tobytes() for i in range(5)}) == 5
