"""auto's blend study (lab/height/blend_study.py): the per-bin fit and ``--apply W``'s
judging numbers on hand-made MAE grids (docs/height-record.md, "Measured: auto's blend
for unseen kinds")."""
import argparse
import csv

import numpy as np
import pytest

from pixgraph_lab.height.blend_study import GRID, fit_weights, judge_weight


def _grid(best_w, depth=1.0, floor=2.0):
    """A sample's MAE over the grid: a V with its minimum ``floor`` at ``best_w``."""
    return floor + depth * np.abs(GRID - best_w)


def test_fit_weights_picks_each_bins_minimum():
    mae = np.array([_grid(0.8), _grid(0.8), _grid(0.3), _grid(0.4)])
    bins = np.array([0, 0, 1, 1])
    w = fit_weights(mae, bins, 3)
    assert w[0] == pytest.approx(0.8)
    assert 0.3 - 1e-9 <= w[1] <= 0.4 + 1e-9          # a flat stretch between the two Vs
    assert w[2] == 1.0                                  # no samples: the learned map


def test_apply_judges_the_blend_only_where_auto_keeps_the_learned_map(tmp_path):
    mae = np.array([_grid(0.8), _grid(0.8), _grid(0.0)])
    rows = [{"category": "a", "use_learned": 1}, {"category": "b", "use_learned": 1},
            {"category": "b", "use_learned": 0}]
    a = argparse.Namespace(apply=0.8, weights="w.pt", heights=["x"], out=str(tmp_path))
    assert judge_weight(a, rows, mae) == 0
    got = list(csv.DictReader(open(tmp_path / "blend_apply.csv")))
    # auto: the learned map (w = 1: 2.2) twice, the contact line (w = 0: 2.0) where it falls back
    assert [float(r["mae_auto"]) for r in got] == pytest.approx([2.2, 2.2, 2.0])
    assert [float(r["mae_blend"]) for r in got] == pytest.approx([2.0, 2.0, 2.0])
    text = (tmp_path / "blend_apply.md").read_text()
    assert "blend - auto -0.133 px" in text


def test_apply_refuses_a_weight_off_the_grid(tmp_path):
    a = argparse.Namespace(apply=0.83, weights="w.pt", heights=["x"], out=str(tmp_path))
    with pytest.raises(SystemExit, match="not on the grid"):
        judge_weight(a, [{"category": "a", "use_learned": 1}], np.array([_grid(0.8)]))


def test_kind_errors_signs_and_halves():
    from pixgraph_lab.height.kind_bias import kind_errors
    mask = np.zeros((12, 6), bool)
    mask[2:12, 1:5] = True                      # box rows 2..11: height 10
    true = np.zeros((12, 6))
    learned = true.copy()
    learned[2:7] += 5.0                          # upper half 5 px too tall
    contact = true - 2.0                         # 2 px too short everywhere
    e = kind_errors(true, learned, contact, mask)
    assert e["signed_upper"] == pytest.approx(0.5) and e["signed_lower"] == pytest.approx(0.0)
    assert e["signed_learned"] == pytest.approx(0.25) and e["abs_learned"] == pytest.approx(0.25)
    assert e["signed_contact"] == pytest.approx(-0.2) and e["abs_contact"] == pytest.approx(0.2)
