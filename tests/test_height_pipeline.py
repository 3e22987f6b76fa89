"""The predictor's lab pipeline at toy size (docs/height.md's commands): generate
cutouts with true pixel heights, train two steps, resume, evaluate. Needs Mitsuba."""
import json

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="Mitsuba 3 not installed: pip install -e .[datagen]")
pytest.importorskip("trimesh", reason="trimesh not installed: pip install -e .[datagen]")
pytest.importorskip("torch")

from pixgraph_lab.height import generate, train  # noqa: E402

pytestmark = pytest.mark.datagen


def test_splits_are_object_disjoint():
    (tr, trp), (va, vap), (te, tep) = (map(set, generate.object_pool(s)) for s in ("train", "val", "test"))
    assert tr and va and te
    assert not (tr & va) and not (tr & te) and not (va & te)
    # procedural kinds: test has its own (figure, tee); val shares train's kinds
    assert tep == {"proc:figure", "proc:tee"} and not (tep & trp) and vap == trp


def test_generated_heights_are_the_visible_surface_heights():
    arrays, meta = generate.make_sample("test", 0, seed=0, res=64)
    cam = meta["camera"]
    m = arrays["mask"]
    h = arrays["height"].astype(np.float32)
    assert m.sum() > 10 and np.all(h[~m] == 0)
    # back-projected (design: Y = H_cam h / (v + h - horizon)), every object pixel lies
    # between the ground and the object's top; this sample's top is in view (measured
    # 0.989 of object_height; heights off by a factor 2 would give 0.634)
    v = np.arange(h.shape[0], dtype=np.float64)[:, None] + 0.5
    Y = (cam["cam_height"] * h / (v + h - cam["horizon"]))[m]
    assert Y.min() > -1e-3 and Y.max() < 1.01 * meta["object_height"]
    assert Y.max() > 0.9 * meta["object_height"] and Y.min() < 0.05 * meta["object_height"]
    # the top of the object is at world height object_height: its pixel height is
    # f Y / D, at most what the object's highest point gives at the nearest depth;
    # and the lowest mask pixels of an object resting on the ground are near 0
    assert h[m].min() < 0.25 * h[m].max()
    assert 0.2 * 64 * 0.5 < h[m].max() < 64
    assert arrays["rgb"].dtype == np.uint8 and arrays["alpha"][m].min() > 0
    # same seed and index: same sample
    a2, meta2 = generate.make_sample("test", 0, seed=0, res=64)
    np.testing.assert_array_equal(a2["height"], arrays["height"])
    assert meta2["object"] == meta["object"]


def test_generate_train_resume_evaluate(tmp_path):
    d = tmp_path / "data"
    for split, n in (("train", 3), ("val", 2), ("test", 2)):
        assert generate.main(["--split", split, "--n", str(n), "--res", "64", "--out", str(d / split)]) == 0
    run = tmp_path / "run"
    args = ["--data", str(d), "--out", str(run), "--size", "32", "--base", "4", "--levels", "2",
            "--batch", "2", "--val-every", "1", "--steps", "6"]
    assert train.main(args + ["--minutes", "0"]) == 0         # stops (time limit) after one step
    assert json.loads((run / "train.json").read_text())["steps"] == 1
    assert train.main(args) == 0                              # resumes at step 1
    info = json.loads((run / "train.json").read_text())
    assert info["steps"] == 6 and [r["step"] for r in info["curve"]] == [1, 2, 3, 4, 5, 6]
    assert (run / "curve.csv").exists() and (run / "best.pt").exists()
    from pixgraph_lab.height import evaluate
    assert evaluate.main(["--heights", str(d / "test"), "--weights", str(run / "best.pt"),
                          "--out", str(tmp_path / "eval")]) == 0
    assert "learned MAE px" in (tmp_path / "eval" / "report.md").read_text()
