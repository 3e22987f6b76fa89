"""lab/evaluate.py and lab/failure.py on a tiny generated benchmark (needs Mitsuba + OpenCL)."""
import csv
import os

import numpy as np
import pytest

pytest.importorskip("mitsuba", reason="Mitsuba 3 not installed: pip install -e .[datagen]")

from pixgraph_lab import evaluate as E  # noqa: E402
from pixgraph_lab import failure as F  # noqa: E402
from pixgraph_lab.datagen import generate  # noqa: E402
from pixgraph_lab.datagen.dataset import load_sample, sample_files  # noqa: E402
from pixgraph_lab.metrics import shadow_metrics  # noqa: E402

pytestmark = pytest.mark.datagen

GRAPH = """pixgraph: 1
nodes:
  camera: {type: pixgraph.Camera}
  light: {type: pixgraph.Light, inputs: {camera: camera.camera}}
  fg_height: {type: pixgraph.LoadPixelHeight, params: {path: unused.npy}}
  bg_height: {type: pixgraph.LoadPixelHeight, params: {path: unused.npy}}
  dummy: {type: pixgraph.LoadImage, params: {path: unused.png}}
  mask: {type: pixgraph.HardShadow, inputs: {mask: dummy.alpha, fg_height: fg_height.height,
         bg_height: bg_height.height, light: light.light, camera: camera.camera}}
  shadow: {type: pixgraph.SoftShadow, params: {samples: 16},
           inputs: {mask: mask.lit, fg_height: fg_height.height, bg_height: bg_height.height,
                    light: light.light, camera: camera.camera}}
outputs: {darkness: shadow.darkness}
"""

ORACLE = """
def oracle(sample):
    return sample["shadow"]

def blank(sample):
    return sample["shadow"] * 0.0
"""


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    out = tmp_path_factory.mktemp("bench") / "wall"
    generate.main(["--benchmark", "wall", "--split", "test", "--n", "3", "--seed", "2", "--out", str(out),
                   "--res", "48", "--light-samples", "16", "--no-progress"])
    return str(out)


def test_baselines_are_always_present_and_renderer_row_is_exact(bench, device):
    rows = E.evaluate(bench, ["renderer_hard", "hard", "soft:4"], device=device, progress=False)
    assert len(rows) == 9
    for f in sample_files(bench):
        s = load_sample(f)
        valid = ~s["mask"] & s["bg_valid"]
        ref = shadow_metrics(s["hard_shadow"].astype(np.float64), s["shadow"].astype(np.float64), valid)
        row = next(r for r in rows if r["method"] == "renderer_hard" and r["index"] == s["meta"]["index"])
        for k in ("rmse", "rmse_s", "ssim", "zncc"):
            assert row[k] == pytest.approx(ref[k], abs=1e-12)
    for r in rows:                                    # thinness from each sample's own mask
        s = load_sample(sample_files(bench)[r["index"]])
        assert r["stroke_width"] == pytest.approx(F.stroke_width(s["mask"]))
        assert 0.0 < r["stroke_width"] <= 0.7
    summ = E.summarize(rows, ["renderer_hard", "hard", "soft:4"])
    assert [r["method"] for r in summ] == ["renderer_hard", "hard", "soft:4"]
    assert all(r["ms"] >= 0 for r in summ)


def test_callable_methods(bench, device, tmp_path, monkeypatch):
    (tmp_path / "oracle_mod.py").write_text(ORACLE)
    monkeypatch.syspath_prepend(str(tmp_path))
    rows = E.evaluate(bench, ["oracle_mod:oracle", "oracle_mod:blank"], device=device, progress=False)
    ora = [r for r in rows if r["method"] == "oracle_mod:oracle"]
    assert all(r["rmse"] == 0.0 and r["ssim"] == pytest.approx(1.0) for r in ora)
    assert all(r["zncc"] == pytest.approx(1.0) for r in ora)
    blank = [r for r in rows if r["method"] == "oracle_mod:blank"]
    assert all(r["zncc"] == 0.0 and r["rmse"] > 0 for r in blank)


def test_graph_method_equals_builtin_soft(bench, device, tmp_path):
    import OpenImageIO as oiio
    np.save(tmp_path / "unused.npy", np.zeros((4, 4), np.float32))
    o = oiio.ImageOutput.create(str(tmp_path / "unused.png"))
    o.open(str(tmp_path / "unused.png"), oiio.ImageSpec(4, 4, 1, "uint8"))
    o.write_image(np.zeros((4, 4, 1), np.uint8))
    o.close()
    (tmp_path / "g.yaml").write_text(GRAPH)
    spec = f"graph:{tmp_path / 'g.yaml'}"
    rows = E.evaluate(bench, ["soft:16", spec], device=device, progress=False)
    a = sorted((r["index"], r["rmse"], r["ssim"]) for r in rows if r["method"] == "soft:16")
    b = sorted((r["index"], r["rmse"], r["ssim"]) for r in rows if r["method"] == spec)
    assert len(a) == 3
    np.testing.assert_allclose(np.array(a), np.array(b), atol=1e-6)


def test_bad_method_spec_fails_early():
    with pytest.raises(ValueError):
        E.Method("nonsense")
    with pytest.raises(ValueError):
        E.Method("soft:0")
    with pytest.raises(FileNotFoundError):
        E.Method("graph:/no/such/graph.yaml")


def test_cli_writes_table_and_charts(bench, tmp_path, capsys):
    out = tmp_path / "ev"
    assert E.main(["--data", bench, "--out", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    for m in E.BASELINES:
        assert f"| {m} |" in text
    for name in ("table.md", "table.csv", "per_sample.csv", "speed_accuracy.png",
                 "failure_elevation_deg.png", "failure_relative_radius.png", "failure_background.png",
                 "failure_stroke_width.png"):
        assert os.path.getsize(out / name) > 0, name
    with open(out / "table.csv") as fh:
        table = list(csv.DictReader(fh))
    assert [r["method"] for r in table] == list(E.BASELINES)
    assert all(0.0 <= float(r["rmse"]) <= 1.0 and -1 <= float(r["zncc"]) <= 1 for r in table)


def test_no_baselines_rows_concatenate_with_an_earlier_evaluation(bench, tmp_path, capsys):
    full, extra = tmp_path / "full", tmp_path / "extra"
    assert E.main(["--data", bench, "--out", str(full), "--no-progress", "--no-failure"]) == 0
    assert E.main(["--data", bench, "--out", str(extra), "--no-progress", "--no-failure",
                   "--no-baselines", "--method", "soft:64"]) == 0
    capsys.readouterr()
    with open(full / "per_sample.csv") as fh:
        rows_full = list(csv.DictReader(fh))
    with open(extra / "per_sample.csv") as fh:
        rows_extra = list(csv.DictReader(fh))
    assert {r["method"] for r in rows_extra} == {"soft:64"}            # nothing else was run
    assert list(rows_extra[0]) == list(rows_full[0])                   # same columns: concatenable
    # the same method on the same samples gives the same errors (deterministic tracer)
    a = {r["index"]: float(r["rmse"]) for r in rows_full if r["method"] == "soft:64"}
    b = {r["index"]: float(r["rmse"]) for r in rows_extra}
    assert a.keys() == b.keys() and all(abs(a[k] - b[k]) < 1e-9 for k in a)
    with pytest.raises(SystemExit):
        E.main(["--data", bench, "--no-baselines"])
