"""auto's confidence: the per-cutout signals (learned_height.confidence_signals), the
rule stored in a checkpoint and the study that chooses it (lab/height/confidence_study.py)."""
import json

import numpy as np
import pytest

from pixgraph_nodes.ops import learned_height as lh
from pixgraph_nodes.ops.heightmaps import contact_line_height


def test_convex_hull_area_of_pixel_squares():
    m = np.zeros((10, 12), bool)
    m[2:6, 3:8] = True
    assert lh.convex_hull_area(m) == pytest.approx(20.0)
    m[2:4, 4:7] = False                      # a notch: the hull keeps the rectangle
    assert lh.convex_hull_area(m) == pytest.approx(20.0)
    t = np.zeros((10, 10), bool)             # a staircase: hull (0,0),(1,0),(4,3),(4,4),(0,4)
    for r in range(4):
        t[r, : r + 1] = True
    assert lh.convex_hull_area(t) == pytest.approx(16 - 0.5 * 3 * 3)
    assert lh.convex_hull_area(np.zeros((3, 3), bool)) == 0.0


def test_confidence_signals_on_a_table():
    m = np.zeros((40, 40), bool)
    m[5:15, 4:36] = True
    m[10:35, 5:8] = True
    m[10:35, 32:35] = True
    heur = contact_line_height(m)
    h = heur + np.where(m, 3.0, 0.0)
    flip = heur + np.where(m, 1.0, 0.0)
    s = lh.confidence_signals(h, heur, m, flip, 2.0, 5.0)
    assert s["disagreement_px"] == pytest.approx(3.0) and s["flip_px"] == pytest.approx(2.0)
    assert s["disagreement_rel"] == pytest.approx(3.0 / 30.0) and s["head_gain_px"] == pytest.approx(-3.0)
    # 32 columns, 6 of them legs standing on the contact line; the top's 26 end 20 rows above it
    assert s["overhang_share"] == pytest.approx(26 / 32)
    # hull (4,5) (36,5) (36,15) (35,35) (5,35) (4,15): 320 + 2 x 0.5 x 1 x 20 + 30 x 20 = 940 px^2
    assert m.sum() == 440 and s["solidity"] == pytest.approx(440 / 940)
    nan = lh.confidence_signals(h, heur, m)
    assert np.isnan(nan["flip_px"]) and np.isnan(nan["head_gain_px"])


def test_rule_value_and_calibration():
    sig = {"disagreement_px": 4.0, "flip_px": 1.0}
    assert lh.confidence_value(sig, {"signal": "disagreement_px", "sign": -1.0}) == -4.0
    comb = {"signal": "combined", "features": ["disagreement_px", "flip_px"], "mean": [2.0, 0.0],
            "std": [2.0, 0.5], "bias": 0.5, "weights": [1.0, -1.0]}
    assert lh.confidence_value(sig, comb) == pytest.approx(0.5 + 1.0 - 2.0)
    rule = {"bins": [-3.0, -1.0], "win_rate": [0.9, 0.7, 0.4]}
    assert [lh.calibrated_confidence(v, rule) for v in (-5.0, -3.0, -2.0, 0.0)] == [0.9, 0.7, 0.7, 0.4]


def test_spearman_and_threshold_of_the_study():
    from pixgraph_lab.height.confidence_study import best_threshold, spearman
    x = np.array([1.0, 2.0, 3.0, 4.0, 5.0])
    assert spearman(x, x ** 3) == pytest.approx(1.0) and spearman(x, -x) == pytest.approx(-1.0)
    assert spearman([1, 1, 2, 2], [1, 2, 3, 4]) == pytest.approx(np.corrcoef([1.5, 1.5, 3.5, 3.5], [1, 2, 3, 4])[0, 1])
    s = np.array([0.0, 1.0, 2.0, 3.0])
    mae_l = np.array([1.0, 1.0, 5.0, 5.0])
    mae_h = np.array([2.0, 2.0, 3.0, 3.0])
    t, m = best_threshold(s, mae_l, mae_h)     # the contact line above s = 1: (1 + 1 + 3 + 3) / 4
    assert t == 1.0 and m == pytest.approx(2.0)
    t, m = best_threshold(s, mae_l, mae_l + 1)  # never fall back
    assert t == float("inf") and m == pytest.approx(3.0)


def test_auto_follows_the_rule_in_the_checkpoint(tmp_path):
    torch = pytest.importorskip("torch")
    from pixgraph.node import Namespace
    from pixgraph_nodes import cutout_height as ch
    from pixgraph_nodes.cutout_height import CutoutHeight
    ck = torch.load(lh.WEIGHTS, map_location="cpu", weights_only=True)
    cfg = json.loads(ck["config"]) if isinstance(ck["config"], str) else dict(ck["config"])
    m = np.zeros((60, 50), np.float32)
    m[10:50, 15:35] = 1
    m[10:20, 5:45] = 1
    img = np.stack([0.4 * m, 0.3 * m, 0.2 * m], -1)
    rgba = np.concatenate([img, m[..., None]], -1)
    ref = lh.LearnedHeightPredictor().predict_full(rgba, signals=True)
    d = ref["signals"]["disagreement_px"]
    assert d > 0
    out = {}
    for name, thr in (("trust", -d + 1e-3), ("fall", -d - 1e-3)):
        cfg["inference"] = dict(cfg.get("inference", {}), confidence={
            "signal": "disagreement_px", "sign": -1.0, "threshold": thr, "bins": [0.0], "win_rate": [0.8, 0.3]})
        ck["config"] = json.dumps(cfg)
        torch.save(ck, tmp_path / f"{name}.pt")
        p = lh.LearnedHeightPredictor(tmp_path / f"{name}.pt")
        r = p.predict_full(rgba)
        assert r["signal"] == pytest.approx(-d, abs=1e-6) and r["confidence"] == 0.8
        assert r["use_learned"] == (name == "trust")

        class Ctx:
            device = graph_dir = None
            logs = []

            def log(self, msg):
                self.logs.append(msg)
        old = ch.learned_predictor
        ch.learned_predictor = lambda p=p: p
        try:
            params = Namespace(CutoutHeight.spec.coerce_params({"method": "auto"}))
            out[name] = CutoutHeight().compute(Ctx(), Namespace({"mask": m, "image": img}), params)
        finally:
            ch.learned_predictor = old
    np.testing.assert_allclose(out["trust"]["height"], ref["height"], atol=1e-5)
    # the fallback: the contact line under the same contact constraint (pinned like the
    # learned map), which is predict_full's heuristic
    np.testing.assert_allclose(out["fall"]["height"], lh.pin_contact(contact_line_height(m), m > 0.5))
    np.testing.assert_allclose(out["fall"]["height"], ref["heuristic"], atol=1e-5)


def test_convex_hull_area_matches_the_hull_of_every_pixel_corner():
    """The running-extreme filter drops only points inside the hull: the same area as
    qhull's hull over all four corners of every mask pixel (an independent reference)."""
    spatial = pytest.importorskip("scipy.spatial")

    def reference(m):
        r, c = np.nonzero(m)
        pts = np.concatenate([np.stack([c + dx, r + dy], 1) for dx in (0, 1) for dy in (0, 1)]).astype(float)
        return spatial.ConvexHull(pts).volume
    rng = np.random.default_rng(0)
    for _ in range(30):
        m = np.zeros((60, 60), bool)
        for _ in range(4):
            r, c = rng.integers(5, 55, 2)
            m[max(r - rng.integers(2, 20), 0):r, max(c - rng.integers(2, 20), 0):c] = True
        assert lh.convex_hull_area(m) == pytest.approx(reference(m), abs=1e-9)
