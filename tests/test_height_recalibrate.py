"""The confidence's recalibration on unseen kinds (lab/height/recalibrate.py): the
win rates per bin, the calibration numbers the rule judged by, and that the shipped
checkpoint carries refitted rates with the validation-chosen signal, threshold and
bins unchanged (docs/height-record.md, "Measured: the confidence on unseen kinds")."""
import json
import pathlib

import numpy as np
import pytest

from pixgraph_lab.height.recalibrate import bin_of, calibration, fit_win_rates
from pixgraph_nodes.ops.learned_height import calibrated_confidence

WEIGHTS = pathlib.Path(__file__).resolve().parents[1] / "nodes" / "weights"


def test_bin_of_is_calibrated_confidences_bin():
    edges = [-3.0, -1.0, 2.0]
    rule = {"bins": edges, "win_rate": [0.1, 0.2, 0.3, 0.4]}
    for s in (-5.0, -3.0, -2.0, -1.0, 0.0, 2.0, 9.0):
        assert rule["win_rate"][int(bin_of(np.array([s]), edges)[0])] == calibrated_confidence(s, rule)


def test_fit_win_rates_per_bin_and_pooled_for_small_bins():
    bins = np.array([0] * 25 + [1] * 30 + [2] * 3)
    win = np.array([True] * 20 + [False] * 5 + [True] * 6 + [False] * 24 + [True] * 3)
    rates = fit_win_rates(bins, win, 4, min_bin=20)
    pooled = 29 / 58
    assert rates == pytest.approx([20 / 25, 6 / 30, pooled, pooled])   # bin 2 (3) and bin 3 (0): pooled
    assert fit_win_rates(bins, win, 4, min_bin=1)[2] == 1.0
    # a bin of exactly min_bin cutouts keeps its own share; one fewer takes the pooled one
    assert fit_win_rates(bins, win, 4, min_bin=25)[0] == pytest.approx(20 / 25)
    assert fit_win_rates(bins, win, 4, min_bin=26)[0] == pytest.approx(pooled)


def test_calibration_numbers():
    # two bins: 10 cutouts said 0.9 and won 5; 30 said 0.5 and won 15
    conf = np.array([0.9] * 10 + [0.5] * 30)
    win = np.array([True] * 5 + [False] * 5 + [True] * 15 + [False] * 15)
    bins = np.array([0] * 10 + [1] * 30)
    c = calibration(conf, win, bins, 2)
    assert c["n"] == 40
    assert c["mean_conf"] == pytest.approx(0.6)
    assert c["win"] == pytest.approx(0.5)
    assert c["gap"] == pytest.approx(0.1)
    assert c["binned_error"] == pytest.approx((10 * 0.4 + 30 * 0.0) / 40)
    # rates refitted on the same cutouts are calibrated on them exactly
    rates = fit_win_rates(bins, win, 2, min_bin=1)
    assert calibration(np.take(rates, bins), win, bins, 2)["binned_error"] == pytest.approx(0.0)
    # saying less than it wins: a negative gap
    assert calibration(np.full(40, 0.3), win, bins, 2)["gap"] == pytest.approx(-0.2)


def test_export_keeps_the_provenance_config_in_step(tmp_path):
    """``recalibrate --write`` changes the .pt's config; ``export --npz`` writes it into
    the provenance JSON beside it (which the test above and docs read)."""
    torch = pytest.importorskip("torch")
    from pixgraph_lab.height.export import write_numpy_weights
    ck = torch.load(WEIGHTS / "cutout_height.pt", map_location="cpu", weights_only=True)
    cfg = json.loads(ck["config"]) if isinstance(ck["config"], str) else ck["config"]
    cfg["inference"]["confidence"]["win_rate"] = [0.1, 0.2, 0.3, 0.4, 0.5]
    ck["config"] = json.dumps(cfg) if isinstance(ck["config"], str) else cfg
    torch.save(ck, tmp_path / "w.pt")
    (tmp_path / "w.json").write_text((WEIGHTS / "cutout_height.json").read_text())
    write_numpy_weights(tmp_path / "w.pt")
    prov = json.loads((tmp_path / "w.json").read_text())
    assert prov["config"] == cfg
    assert prov["numpy_weights"]["bytes"] == (tmp_path / "w.npz").stat().st_size


def test_shipped_rule_refitted_on_unseen_kinds_only_in_its_rates():
    cfg = json.loads((WEIGHTS / "cutout_height.json").read_text())["config"]["inference"]["confidence"]
    assert cfg["chosen_on"].startswith("data/hreal/val ")              # signal, threshold, bins
    assert "u4_heldout" in cfg["win_rate_chosen_on"]                   # the rates
    assert len(cfg["win_rate"]) == len(cfg["bins"]) + 1
    # fitted on the three held-out sets, not validation's rates: all well below them
    assert max(cfg["win_rate"]) < 0.75 and min(cfg["win_rate"]) > 0.45
    # auto's choice is the threshold's, which lies in the top bin
    assert cfg["threshold"] > cfg["bins"][-1]
    # what the node reads (the numpy weights' config) is the provenance's rule
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor
    assert LearnedHeightPredictor().confidence_rule == cfg


def test_folder_rows_cache_is_per_folder_path_and_weights(tmp_path, monkeypatch):
    """Two folders of one name, or other weights, are predicted again, not read from
    another's cache; the same folder and weights are read back."""
    from pixgraph_lab.height import evaluate, recalibrate

    calls = []
    mask = np.ones((4, 4), bool)
    monkeypatch.setattr(evaluate, "height_files", lambda folder: [folder + "/0.npz"])
    monkeypatch.setattr(evaluate, "read_height_sample",
                        lambda f: ({"index": 0, "object": f}, None, np.full((4, 4), 2.0), mask))

    class Pred:
        def __init__(self, path, h):
            self.path, self.h = path, h

        def predict_full(self, rgba):
            calls.append(self.path)
            return {"signal": -1.0, "height": np.full((4, 4), self.h), "heuristic": np.zeros((4, 4)),
                    "use_learned": True}
    w1, w2 = tmp_path / "a.pt", tmp_path / "b.pt"
    w1.write_bytes(b"one")
    w2.write_bytes(b"two")
    out = str(tmp_path / "out")
    d1, d2 = str(tmp_path / "x" / "val"), str(tmp_path / "y" / "val")
    r = recalibrate.folder_rows(d1, Pred(w1, 3.0), out)
    assert r[0]["mae_learned"] == pytest.approx(1.0) and len(calls) == 1
    assert recalibrate.folder_rows(d1, Pred(w1, 9.0), out)[0]["mae_learned"] == pytest.approx(1.0)
    assert len(calls) == 1                                            # read back
    assert recalibrate.folder_rows(d2, Pred(w1, 5.0), out)[0]["mae_learned"] == pytest.approx(3.0)
    assert recalibrate.folder_rows(d1, Pred(w2, 6.0), out)[0]["mae_learned"] == pytest.approx(4.0)
    assert len(calls) == 3
