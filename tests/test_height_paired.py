"""``pixgraph_lab.height.paired`` (two evaluate_real runs compared per sample) and the
bootstrap interval it shares with ``scale_study``, on hand-made heights.csv files."""
import csv

import numpy as np
import pytest

from pixgraph_lab.height import paired, scale_study


def rows(objects, learned, heuristic, baseline):
    return [{"object": o, "mae_learned": a, "mae_heuristic": h, "mae_baseline": b}
            for o, a, h, b in zip(objects, learned, heuristic, baseline)]


def test_interval_is_the_percentile_bootstrap_of_the_mean():
    d = np.random.default_rng(3).normal(0.5, 2.0, 40)
    rng = np.random.default_rng(0)                  # the reference, written out
    means = np.array([d[rng.integers(0, 40, 40)].mean() for _ in range(10000)])
    lo, hi = scale_study.interval(d)
    assert lo == pytest.approx(np.quantile(means, 0.025)) and hi == pytest.approx(np.quantile(means, 0.975))
    assert lo < d.mean() < hi and scale_study.upper_bound(d) == hi
    assert scale_study.interval(np.full(9, -1.25)) == (-1.25, -1.25)     # no spread, no width


def test_compare_per_kind_and_against_the_baseline_column():
    a = rows(["k/x", "k/y", "k/x", "k/y"], [1.0, 4.0, 3.0, 2.0], [2.0, 3.0, 2.0, 3.0], [9, 9, 9, 9])
    b = rows(["k/x", "k/y", "k/x", "k/y"], [2.0, 5.0, 4.0, 3.0], [2.0, 3.0, 2.0, 3.0], [0, 0, 0, 0])
    table, (m, lo, hi) = paired.compare(a, b)
    assert [r[0] for r in table] == ["all", "k/x", "k/y"] and [r[1] for r in table] == [4, 2, 2]
    assert table[0][2:5] == (2.5, 3.5, 2.5)
    assert table[1][2:] == (2.0, 3.0, 2.0, 0.5, 0.0)          # k/x: A beats 2.0 once (1.0), B never
    assert table[2][2:] == (3.0, 4.0, 3.0, 0.5, 0.0)
    assert (m, lo, hi) == (-1.0, -1.0, -1.0)                  # every sample 1 px better
    table, (m, _, _) = paired.compare(a)                      # B = A's baseline column
    assert table[0][3] == 9.0 and m == -6.5
    with pytest.raises(ValueError, match="not on the same samples"):
        paired.compare(a, b[::-1])


def test_main_reads_two_run_folders(tmp_path, capsys):
    for name, learned in (("a", [1.0, 2.0, 6.0]), ("b", [2.0, 2.0, 3.0])):
        (tmp_path / name).mkdir()
        with open(tmp_path / name / "heights.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["index", "category", "object", "mae_learned", "mae_heuristic", "mae_baseline"])
            for i, v in enumerate(learned):
                w.writerow([i, "c", f"c/{'pq'[i % 2]}", v, 4.0, 5.0])
    assert paired.main([str(tmp_path / "a"), str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out
    assert "| all | 3 | 3.000 | 2.333 | 4.000 | 66.7 % | 100.0 % |" in out
    assert "| c/p | 2 | 3.500 | 2.500 | 4.000 | 50.0 % | 100.0 % |" in out
    assert "A - B: +0.667 px" in out
    assert paired.main([str(tmp_path / "a"), str(tmp_path / "b"), "--exclude", "c/q"]) == 0
    out = capsys.readouterr().out
    assert "| all | 2 | 3.500 | 2.500 | 4.000 | 50.0 % | 100.0 % |" in out and "| c/q |" not in out
