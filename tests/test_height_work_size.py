"""The large-cutout candidate that did not ship (lab/height/work_size.py: predict at
the validated size, bring the map back): what its study (scale_study) relies on, and
the finding that made it a candidate: the shipped path's confidence signal grows with
the cutout's pixel size."""
import numpy as np
import pytest

torch = pytest.importorskip("torch")
from pixgraph_lab.height import work_size as hw  # noqa: E402
from pixgraph_nodes.ops import learned_height as lh  # noqa: E402

from test_learned_height import REAL, heldout  # noqa: E402


def big(a, k):
    return np.repeat(np.repeat(a, k, axis=0), k, axis=1)


def shrink(a, k):
    H, W = a.shape
    return a.reshape(H // k, k, W // k, k).mean((1, 3))


@pytest.fixture(scope="module")
def predictor():
    return lh.LearnedHeightPredictor()


@pytest.fixture(scope="module")
def samples():
    return [np.concatenate([s["image"], s["alpha"][..., None]], -1) for s in heldout(REAL)[:4]]


def test_a_large_cutout_gives_the_same_heights_and_confidence_at_any_size(predictor, samples):
    # 8x and 16x the same cutout: the candidate predicts both at the work size, so the maps
    # agree (16x block-averaged down to 8x, heights halved) and so does auto's signal
    edges = predictor.confidence_rule["bins"]
    tol = 0.15 * (edges[-1] - edges[0])   # resampling noise: the two work images differ
    for rgba in samples:
        r8, r16 = hw.predict_at_work_size(predictor, big(rgba, 8)), hw.predict_at_work_size(predictor, big(rgba, 16))
        assert r8["work_scale"] > 1 and r16["work_scale"] == pytest.approx(2 * r8["work_scale"], rel=0.02)
        m = big(rgba[..., 3], 8) > 0.5
        err = np.abs(shrink(r16["height"], 2)[m] / 2 - r8["height"][m]).mean()
        assert err < 0.02 * r8["height"].max(), err     # 0.2-1.2 % on these four
        assert abs(r16["signal"] - r8["signal"]) <= tol, (r8["signal"], r16["signal"])


def test_a_large_cutouts_signal_grows_with_its_size_unless_measured_at_signal_side(predictor, samples):
    # the shipped path runs at the cutout's own size and measures the confidence signal's
    # lengths in its pixels: from 8x to 16x the signal doubled on three of these four
    # (-19 -> -40, -14 -> -31, -73 -> -147). With signal_side = SIGNAL_SIDE (not shipped:
    # docs/height.md, "Measured: auto's blend and large cutouts") it stays put
    edges = predictor.confidence_rule["bins"]
    tol = 0.15 * (edges[-1] - edges[0])
    assert predictor.signal_side is None
    grew = []
    for side in (None, lh.SIGNAL_SIDE):
        predictor.signal_side = side
        try:
            sig = [[predictor.predict_full(big(rgba, k))["signal"] for k in (8, 16)] for rgba in samples]
        finally:
            predictor.signal_side = None
        grew.append(sum(abs(b - a) > tol for a, b in sig))
    assert grew[0] >= 3 and grew[1] == 0, grew


def test_cutouts_up_to_the_work_size_are_untouched(predictor, samples):
    side = lh.crop_box(samples[0][..., 3] > 0.5)[6]
    assert side <= hw.WORK_SIDE
    a, b = hw.predict_at_work_size(predictor, samples[0]), predictor.predict_full(samples[0])
    assert "work_scale" not in a
    np.testing.assert_array_equal(a["height"], b["height"])
    assert a["signal"] == b["signal"]


@pytest.mark.parametrize("contact,lift", [("ground", 0.0), ("lifted", 40.0)])
def test_the_contact_is_pinned_at_full_size(predictor, samples, contact, lift):
    rgba = big(samples[1], 12)
    r = hw.predict_at_work_size(predictor, rgba, contact=contact, lift=lift)
    mask = rgba[..., 3] > 0.5
    band = lh.contact_band(mask)
    assert r["work_scale"] > 1
    assert r["height"].shape == mask.shape and np.all(r["height"][~mask] == 0)
    # the pin's mean over the full-size contact pixels, before clipping at 0
    assert r["height"][band].mean() == pytest.approx(lift, abs=0.05 * r["work_scale"] + 1e-3)
    assert r["heuristic"][band].mean() == pytest.approx(lift, abs=0.6)
    # heights are full-size pixels: the object's top is about as high as its contact line says
    top = r["heuristic"].max()
    assert 0.2 * top < r["height"].max() < 1.5 * top


def test_shrink_cutout_reads_only_the_covered_box():
    rgba = np.zeros((600, 900, 4), np.float32)
    rgba[100:400, 300:500] = (0.2, 0.3, 0.4, 1.0)
    f, shape = hw.work_shape(600, 900, 400)
    assert f == pytest.approx(400 / hw.WORK_SIDE) and shape == (round(600 / f), round(900 / f))
    small = hw.shrink_cutout(rgba, shape)
    # area kept (alpha sums scale by 1 / f^2) and the colour inside unchanged
    assert small[..., 3].sum() == pytest.approx(rgba[..., 3].sum() / f ** 2, rel=0.01)
    inside = small[..., 3] > 0.999
    np.testing.assert_allclose(small[inside, :3], np.broadcast_to([0.2, 0.3, 0.4], (int(inside.sum()), 3)), atol=1e-5)
    assert hw.work_shape(600, 900, hw.WORK_SIDE) == (1.0, (600, 900))
