"""The contact as a constraint (learned_height.pin_contact) and CutoutHeight's auto / contact / confidence."""
import math

import numpy as np
import pytest

from pixgraph.node import Namespace
from pixgraph_nodes import cutout_height as ch
from pixgraph_nodes.cutout_height import CutoutHeight
from pixgraph_nodes.ops.heightmaps import contact_line_height
from pixgraph_nodes.ops.learned_height import contact_band, pin_contact


class Ctx:
    device = None
    graph_dir = None

    def __init__(self):
        self.logs = []

    def log(self, message):
        self.logs.append(message)


def run(mask, image, **p):
    params = Namespace(CutoutHeight.spec.coerce_params(p))
    ctx = Ctx()
    return CutoutHeight().compute(ctx, Namespace({"mask": mask, "image": image}), params), ctx


def blob():
    m = np.zeros((40, 30), bool)
    m[5:30, 8:22] = True
    m[30:33, 10:14] = True            # a foot: the lowest rows are 30..32
    return m


def test_contact_band_is_the_lowest_rows():
    m = blob()
    b = contact_band(m, 1.5)
    assert b.sum() == 4 * 2 and b[31:33, 10:14].all() and not b[30].any()
    assert contact_band(m, 1.0).sum() == 4 and contact_band(np.zeros((3, 3), bool)).sum() == 0


def test_pin_shifts_the_whole_map_to_the_contact():
    m = blob()
    v, u = np.mgrid[0:40, 0:30] + 0.5
    h = np.where(m, 33.0 - v + 4.0 + 0.1 * u, 0.0)          # 4 px too high everywhere
    out = pin_contact(h, m)
    b = contact_band(m)
    off = h[b].mean()
    assert abs((h[b] - off).mean()) < 1e-9 and off == pytest.approx(4.0 + 1.0 + 0.1 * 12.0)   # rows 31, 32: 33 - v = 1.5, 0.5
    np.testing.assert_allclose(out[b], np.maximum(h[b] - off, 0), atol=1e-5)   # clipped at 0
    keep = m & (h - off > 0)
    np.testing.assert_allclose(out[keep], (h - off)[keep], atol=1e-5)   # shape kept
    assert np.all(out[~m] == 0) and np.all(out >= 0)
    lifted = pin_contact(h, m, lift=7.5)            # nothing clipped: the mean is the lift
    assert lifted[b].mean() == pytest.approx(7.5, abs=1e-5)


def test_auto_follows_the_confidence(monkeypatch):
    m = blob().astype(np.float32)
    img = np.repeat(m[..., None], 3, 2) * 0.5
    learned = np.where(m > 0.5, 11.0, 0.0).astype(np.float32)

    class Fake:
        def __init__(self, conf):
            self.conf = conf

        def predict_full(self, rgba, contact="ground", lift=0.0):
            return {"height": learned, "heuristic": None, "confidence": self.conf,
                    "est_mae_learned": 1.0, "est_mae_heuristic": 2.0}

    monkeypatch.setattr(ch, "learned_predictor", lambda: Fake(0.7))
    out, ctx = run(m, img, method="auto")
    np.testing.assert_array_equal(out["height"], learned)
    assert out["confidence"] == pytest.approx(0.7)
    monkeypatch.setattr(ch, "learned_predictor", lambda: Fake(0.3))
    out, ctx = run(m, img, method="auto")
    # the contact line under the same constraint as the learned map: its contact pixels'
    # mean pinned to the ground (or the lift), as the studies measured auto
    b = contact_band(m > 0.5)
    np.testing.assert_allclose(out["height"], pin_contact(contact_line_height(m), m > 0.5))
    # (the contact line's own band sits above the ground: the pin lowers it; clipped at 0)
    assert out["height"][b].mean() < contact_line_height(m)[b].mean() - 0.2
    assert "contact line" in ctx.logs[-1] and out["confidence"] == pytest.approx(0.3)
    out, _ = run(m, img, method="auto", contact="lifted", lift=5.0)
    np.testing.assert_allclose(out["height"], pin_contact(contact_line_height(m), m > 0.5, 5.0))
    assert out["height"][b].mean() == pytest.approx(5.0, abs=1e-5)
    # method learned ignores the confidence
    out, _ = run(m, img, method="learned")
    np.testing.assert_array_equal(out["height"], learned)
    # heuristics report no confidence
    out, _ = run(m, None, method="contact_line")
    assert math.isnan(out["confidence"])


def test_shipped_learned_height_stands_on_the_ground_or_is_lifted():
    pytest.importorskip("torch")
    m = blob().astype(np.float32)
    v, u = np.mgrid[0:40, 0:30] + 0.5
    img = np.stack([0.3 + 0.01 * u, 0.2 + 0.005 * v, 0.4 * np.ones_like(u)], -1) * m[..., None]
    b = contact_band(m > 0.5)
    out, _ = run(m, img.astype(np.float32), method="learned")
    assert out["height"][b].max() < 1.0    # the foot within 1 px of the ground (the goal)
    assert 0.0 <= out["confidence"] <= 1.0 or math.isnan(out["confidence"])
    lifted, _ = run(m, img.astype(np.float32), method="learned", contact="lifted", lift=6.0)
    assert lifted["height"][b].mean() == pytest.approx(6.0, abs=1e-4)


def table():
    """A table seen from above: a top (rows 5..14) and four legs; the back legs end
    higher in the image (row 24) than the front ones (row 34)."""
    m = np.zeros((40, 40), bool)
    m[5:15, 4:36] = True
    for c0, r1 in ((5, 35), (31, 35), (10, 25), (26, 25)):
        m[10:r1, c0:c0 + 3] = True
    return m


def test_lower_hull_of_the_column_bottoms():
    from pixgraph_nodes.ops.learned_height import lower_hull_rows
    u = np.arange(11.0)
    tent = 20.0 - np.abs(u - 5.0)               # a turned brick's two bottom edges: all on the hull
    np.testing.assert_allclose(lower_hull_rows(tent), tent)
    gap = np.full(11, 12.0)
    gap[[0, 10]] = 20.0                         # two feet and the underside between them
    gap[3] = np.nan                             # an empty column
    hr = lower_hull_rows(gap)
    assert np.isnan(hr[3]) and np.allclose(hr[np.isfinite(gap)], 20.0)
    bowl = 10.0 + 0.2 * (u - 5.0) ** 2          # the ends are the lowest: the hull is their chord
    np.testing.assert_allclose(lower_hull_rows(bowl), 15.0)


def test_snap_feet_puts_every_foot_on_the_ground():
    from pixgraph_nodes.ops.learned_height import snap_feet
    m = table()
    v = np.arange(40)[:, None] + 0.5
    rows = np.nonzero(m.any(1))[0]
    bh = rows.max() - rows.min() + 1
    # the pinned map: front feet right (0.5 px at the lowest row), back feet 2.5 px too high,
    # the top's underside (columns between the legs) 9.5 px up and right
    h = np.zeros(m.shape)
    for c in range(40):
        if not m[:, c].any():
            continue
        low = np.nonzero(m[:, c])[0].max()
        err = 2.0 if c in (10, 11, 12, 26, 27, 28) else 0.0
        if low == 14:                            # the top alone: its underside 9.5 px above the ground
            err = 9.0
        h[:, c] = low + 1 - v[:, 0] + err
    h = np.where(m, h, 0.0)
    out = snap_feet(h, m, tol=3.0, hull=False, fade=0.25)
    for c in (10, 11, 12, 26, 27, 28):           # back feet: 2.5 -> 0 at the lowest pixel
        assert out[24, c] == pytest.approx(0.0, abs=1e-6)
        r = 20                                   # 4 rows up: the shift has faded by 4 / (0.25 bh)
        assert out[r, c] == pytest.approx(h[r, c] - 2.5 * (1 - 4 / (0.25 * bh)), abs=1e-5)
        assert out[5, c] == pytest.approx(h[5, c])   # above the fade: unchanged
    # front feet (0.5 < tol): snapped to exactly 0; the underside (9.5 px) is kept
    assert out[34, 5] == 0.0 and out[34, 32] == 0.0
    np.testing.assert_allclose(out[:, 18:24], h[:, 18:24])
    assert np.all(out[~m] == 0) and np.all(out >= 0)
    # tol below the back feet's height: they stay; tol 0: nothing changes
    np.testing.assert_allclose(snap_feet(h, m, tol=2.0)[24, 10:13], 2.5)
    np.testing.assert_allclose(snap_feet(h, m, tol=0.0), h)
    # hull on: the back legs' bottoms (row 25) are 10 rows above the front feet's chord: not snapped
    np.testing.assert_allclose(snap_feet(h, m, tol=3.0, hull=True)[24, 10:13], 2.5)


def test_the_shipped_predictor_snaps_its_feet_when_the_checkpoint_says_so():
    pytest.importorskip("torch")
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor, snap_feet
    m = table()
    v, u = np.mgrid[0:40, 0:40] + 0.5
    a = m.astype(np.float32)
    rgba = np.stack([0.3 * a, (0.2 + 0.004 * v) * a, 0.25 * a, a], -1).astype(np.float32)
    off = LearnedHeightPredictor(foot_snap=None).predict(rgba)
    on = LearnedHeightPredictor(foot_snap={"tol": 4.0, "hull": False}).predict(rgba)
    np.testing.assert_allclose(on, snap_feet(off, m, 4.0, False), atol=1e-5)
    low = 39 - np.argmax(m[::-1], axis=0)
    cols = np.nonzero(m.any(0))[0]
    hb = off[low[cols], cols]
    assert np.all(on[low[cols], cols][hb < 4.0] == 0.0)
    # lifted objects are not snapped to the ground
    lifted = LearnedHeightPredictor(foot_snap={"tol": 4.0, "hull": False}).predict(rgba, contact="lifted", lift=5.0)
    np.testing.assert_allclose(lifted, LearnedHeightPredictor(foot_snap=None).predict(rgba, contact="lifted", lift=5.0))
