"""lab/failure.py: the thinness factor (stroke_width) and the binned breaking points, on synthetic input."""
import csv

import numpy as np
import pytest

from pixgraph_lab import failure as F


def _square():
    m = np.zeros((128, 128), bool)
    m[14:114, 14:114] = True
    return m


def test_stroke_width_of_a_filled_square_and_a_thin_frame():
    square = _square()
    frame = square.copy()
    frame[18:110, 18:110] = False                   # a 100 px frame, 4 px wide
    s, f = F.stroke_width(square), F.stroke_width(frame)
    # a filled square: mean distance to the edge is side/6, so 4 x mean / side = 2/3
    assert s == pytest.approx(2 / 3, abs=0.005)
    # a long stroke: 4 x mean distance = its width (4 px), over the 100 px box (corners add a little)
    assert f == pytest.approx(0.04, abs=0.002)
    assert f < 0.1 < s
    # scale-free: the same square at half the size
    assert F.stroke_width(square[::2, ::2]) == pytest.approx(s, abs=0.01)
    assert np.isnan(F.stroke_width(np.zeros((8, 8))))


def test_thin_open_objects_land_in_the_thin_bins():
    table = np.zeros((128, 128), bool)
    table[40:46, 10:118] = True                     # top
    table[46:120, 14:20] = table[46:120, 108:114] = True   # legs
    arch = np.zeros((128, 128), bool)
    arch[20:120, 20:108] = True
    arch[32:120, 32:96] = False
    post = np.zeros((128, 128), bool)
    post[10:120, 60:66] = True
    yy, xx = np.mgrid[:128, :128]
    disc = (yy - 64) ** 2 + (xx - 64) ** 2 < 50 ** 2
    edges = F.FACTORS["stroke_width"][1]
    for thin in (table, arch, post):
        assert F.stroke_width(thin) < edges[2]       # the two thinnest bins
    assert F.stroke_width(disc) > edges[-3]          # the two thickest
    assert F.stroke_width(table) < F.stroke_width(arch) < F.stroke_width(disc)


def test_breaking_point_lines_and_bin_table(tmp_path, capsys):
    rng = np.random.default_rng(0)
    rows = []
    for i in range(60):
        w = float(rng.uniform(0.05, 0.6))
        el = float(rng.uniform(5, 80))
        for m, err in (("good", 0.02), ("thinbad", 0.1 if w < 0.1 else 0.02)):
            rows.append({"index": i, "method": m, "rmse": err, "background": "wall", "stroke_width": w,
                         "elevation_deg": el, "relative_radius": 0.1, "wall_clearance": float("nan")})
    path = tmp_path / "per_sample.csv"
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    assert F.main(["--rows", str(path), "--out", str(tmp_path), "--prefix", "s_", "--tables",
                   "--method", "thinbad"]) == 0
    out = capsys.readouterr().out
    n_thin = sum(r["stroke_width"] < 0.1 for r in rows if r["method"] == "thinbad")
    mean = np.mean([r["rmse"] for r in rows if r["method"] == "thinbad"])
    line = next(ln for ln in out.splitlines() if "thinbad | cutout stroke width" in ln)
    assert f"worst bin [0.03, 0.1) RMSE 0.1000 = {0.1 / mean:.2f}x its mean {mean:.4f} (n={n_thin})" in line
    assert "good" not in out
    assert f"[0.03, 0.1) n={n_thin}" in out
    for key in ("stroke_width", "elevation_deg", "relative_radius", "background"):
        assert (tmp_path / f"s_{key}.png").stat().st_size > 0
    assert not (tmp_path / "s_wall_clearance.png").exists()   # no finite values: no chart
