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
    np.testing.assert_allclose(out["height"], contact_line_height(m))
    assert "contact line" in ctx.logs[-1] and out["confidence"] == pytest.approx(0.3)
    out, _ = run(m, img, method="auto", contact="lifted", lift=5.0)
    np.testing.assert_allclose(out["height"], np.where(m > 0.5, contact_line_height(m) + 5.0, 0.0))
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
