"""Batch runs: manifests and sweeps give the same pixels as single runs, resume
skips done rows (by content key), a bad row is reported while the rest complete,
rows that differ only downstream share their upstream work, and the process-pool
and Dask executors give the in-process results. Safety: test_batch_safety.py."""
import json
import os

import numpy as np
import pytest

import pixgraph_batch.files as F
import pixgraph_batch.runner as B
from pixgraph_batch import batch as run_batch
from pixgraph.cli import main
from pixgraph.registry import Registry
from pixgraph.session import Session
from pixgraph_nodes.ops.imageio import read_image, write_image

N = 64  # small images: the point is equality, not quality

GRAPH = """\
pixgraph: 1
nodes:
  cutout: {type: pixgraph.LoadImage, params: {path: cutouts/c0.png}}
  photo:  {type: pixgraph.LoadImage, params: {path: photo.png}}
  cam:    {type: pixgraph.Camera, params: {width: 64, height: 64, hfov: 50, horizon: 10}}
  fg_h:   {type: pixgraph.CutoutHeight, inputs: {mask: cutout.alpha}}
  bg_h:   {type: pixgraph.BackgroundHeight, inputs: {camera: cam.camera}, params: {kind: ground}}
  light:
    type: pixgraph.Light
    inputs: {camera: cam.camera, mask: cutout.alpha}
    params: {kind: disk, azimuth: -50, elevation: 35, distance: 4, radius: 0.3}
  shadow:
    type: pixgraph.SoftShadow
    inputs: {mask: cutout.alpha, fg_height: fg_h.height, bg_height: bg_h.height, light: light.light, camera: cam.camera}
    params: {samples: 8}
  comp:
    type: pixgraph.Composite
    inputs: {background: photo.image, cutout: cutout.image, alpha: cutout.alpha, shadow: shadow.darkness}
outputs: {final: comp.image, shadow: shadow.darkness}
"""


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """A 64x64 photo, five cutouts and the graph, in one folder."""
    d = tmp_path_factory.mktemp("batch_scene")
    rng = np.random.default_rng(0)
    photo = np.concatenate([rng.uniform(0.2, 0.8, (N, N, 3)), np.ones((N, N, 1))], -1).astype(np.float32)
    write_image(d / "photo.png", photo)
    (d / "cutouts").mkdir()
    for k in range(5):
        a = np.zeros((N, N), np.float32)
        a[14 + k:52, 24 + k:34 + 2 * k] = 1
        write_image(d / "cutouts" / f"c{k}.png", np.dstack([a * 0.8, a * (0.2 + 0.1 * k), a * 0.3, a]))
    (d / "g.yaml").write_text(GRAPH)
    return d


def _manifest(path, n, bad=()):
    """A CSV manifest next to the graph (its relative cutout paths are resolved against its folder)."""
    lines = ["id,cutout.path,light.azimuth,light.elevation"]
    for i in range(n):
        cut = "cutouts/missing.png" if i in bad else f"cutouts/c{i % 5}.png"
        lines.append(f"r{i:02d},{cut},{-170 + 7 * i},{25 + i % 4 * 5}")
    path.write_text("\n".join(lines) + "\n")
    return path


def _pixels(path):
    return read_image(path)[0]


def test_fifty_row_manifest_equals_fifty_single_runs(scene, tmp_path, capsys):
    man = _manifest(scene / f"{tmp_path.name}.csv", 50)
    out = tmp_path / "out"
    reg = Registry.discover()
    rc = main(["batch", str(scene / "g.yaml"), str(man), "-o", f"final={out}/{{row}}.exr", "--no-disk-cache"], reg)
    assert rc == 0, capsys.readouterr()
    assert "50 done, 0 skipped" in capsys.readouterr().out
    for i in range(50):
        single = tmp_path / "single" / f"{i}.exr"
        rc = main(["run", str(scene / "g.yaml"), "--no-disk-cache", "-q",
                   "--set", f"cutout.path={scene}/cutouts/c{i % 5}.png",
                   "--set", f"light.azimuth={-170 + 7 * i}", "--set", f"light.elevation={25 + i % 4 * 5}",
                   "-o", f"final={single}"], reg)
        assert rc == 0
        a, b = _pixels(out / f"r{i:02d}.exr"), _pixels(single)
        assert a.dtype == np.float32 and np.array_equal(a, b), f"row {i} differs from its single run"
    # the rows differ from each other (the overrides took effect)
    assert not np.array_equal(_pixels(out / "r00.exr"), _pixels(out / "r05.exr"))
    # provenance sidecar: params as run, graph hash, version, the node types/methods, the file's hash
    meta = json.loads((out / "r07.exr.json").read_text())
    assert meta["params"] == {"cutout.path": str(scene / "cutouts" / "c2.png"), "light.azimuth": -121,
                              "light.elevation": 40}
    assert meta["pixgraph"] and len(meta["graph_sha256"]) == 64
    assert meta["methods"]["fg_h"]["method"] == "contact_line"
    assert meta["methods"]["shadow"]["type"] == "pixgraph.SoftShadow"
    assert meta["file_sha256"] == F.file_sha256(str(out / "r07.exr"))


def test_bad_rows_are_reported_and_the_rest_complete(scene, tmp_path, capsys):
    man = _manifest(scene / f"{tmp_path.name}.csv", 8, bad={2})
    text = man.read_text().splitlines()
    assert text[5] == "r04,cutouts/c4.png,-142,25"
    text[5] = "r04,cutouts/c4.png,-142,400"
    man.write_text("\n".join(text) + "\n")  # row r04: elevation 400 is out of range
    report = tmp_path / "report.json"
    rc = main(["batch", str(scene / "g.yaml"), str(man), "-o", f"final={tmp_path}/out/{{row}}.png",
               "--no-disk-cache", "--report", str(report)])
    out = capsys.readouterr().out
    assert rc == 1
    assert "6 done, 0 skipped (already done), 2 failed" in out
    table = [line for line in out.splitlines() if line.startswith("r0")]
    assert len(table) == 2 and table[0].startswith("r02") and "missing.png" in table[0]
    assert table[1].startswith("r04") and "elevation" in table[1]
    rows = json.loads(report.read_text())["rows"]
    assert [r["status"] for r in rows] == ["done", "done", "failed", "done", "failed", "done", "done", "done"]
    assert sorted(os.listdir(tmp_path / "out")) == sorted(
        f"r{i:02d}.png{ext}" for i in (0, 1, 3, 5, 6, 7) for ext in ("", ".json"))


# resume after kill -9: tests/test_batch_safety.py::test_resume_after_kill_mid_write kills the
# batch at a chosen point (in the middle of a row's write), not by hoping rows are slow


def test_changed_input_rerenders_only_its_rows(scene, tmp_path):
    s = Session()
    (tmp_path / "cut").mkdir()
    for k in range(2):
        (tmp_path / "cut" / f"c{k}.png").write_bytes((scene / "cutouts" / f"c{k}.png").read_bytes())
    sweeps = [f"cutout.path={tmp_path}/cut/*.png", "light.azimuth=0:90:30"]
    kw = dict(outputs={"final": str(tmp_path / "out/{stem}_{light_azimuth}.png")}, sweeps=sweeps)
    first = run_batch(s, scene / "g.yaml", **kw)
    assert (first.count("done"), first.count("skipped")) == (6, 0)
    assert run_batch(s, scene / "g.yaml", **kw).count("skipped") == 6
    (tmp_path / "cut" / "c1.png").write_bytes((scene / "cutouts" / "c3.png").read_bytes())
    third = run_batch(s, scene / "g.yaml", **kw)
    assert [r.status for r in third.results] == ["skipped"] * 3 + ["done"] * 3
    # a file changed behind the batch's back is rendered again too
    (tmp_path / "out" / "c0_30.png").write_bytes(b"not the image")
    assert [r.row for r in run_batch(s, scene / "g.yaml", **kw).results if r.status == "done"] == ["0001"]


def test_sweep_and_manifest_parsing(tmp_path):
    assert B.parse_sweep("light.azimuth=0:360:15") == ("light.azimuth", list(range(0, 360, 15)))
    assert B.parse_sweep("light.radius=0.1:0.4:0.1")[1] == pytest.approx([0.1, 0.2, 0.3])
    assert B.parse_sweep("light.kind=disk,point") == ("light.kind", ["disk", "point"])
    with pytest.raises(B.BatchError, match="empty"):
        B.parse_sweep("light.azimuth=10:0:5")
    (tmp_path / "m.yaml").write_text("- {id: a, light: {azimuth: 5}, cutout.path: x.png}\n- {light.azimuth: 7}\n")
    rows = B.read_manifest(tmp_path / "m.yaml")
    assert rows[0].id == "a" and rows[0].params == {"light.azimuth": 5, "cutout.path": "x.png"}
    crossed = B.sweep_rows([("light.elevation", [10, 20])], rows)
    assert [dict(r.params) for r in crossed][1:3] == [
        {"light.azimuth": 5, "cutout.path": "x.png", "light.elevation": 20},
        {"light.azimuth": 7, "light.elevation": 10}]


def test_bad_manifest_is_exit_2_naming_file_and_line(scene, tmp_path, capsys):
    man = tmp_path / "rows.csv"
    man.write_text("lamp.azimuth\n10\n")
    assert main(["batch", str(scene / "g.yaml"), str(man)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"{man}:2: column 'lamp.azimuth': no node 'lamp'") and "\n" not in err
    man.write_text("light.azimuth\n10\n20\n")
    assert main(["batch", str(scene / "g.yaml"), str(man), "-o", f"final={tmp_path}/same.png"]) == 2
    assert "output final and row 0001 output final both write" in capsys.readouterr().err


def _sweep_kw(tmp_path, scene, name):
    return dict(outputs={"final": str(tmp_path / name / "{row}.exr"), "shadow": str(tmp_path / name / "{row}_s.exr")},
                sweeps=[f"cutout.path={scene}/cutouts/c[0-2].png", "light.azimuth=-60:60:60"])


def _same_files(tmp_path, a, b, n):
    for i in range(n):
        for suffix in ("", "_s"):
            pa, pb = tmp_path / a / f"{i:04d}{suffix}.exr", tmp_path / b / f"{i:04d}{suffix}.exr"
            assert np.array_equal(_pixels(pa), _pixels(pb)), f"{pb} differs"


def test_dask_local_cluster_matches_in_process(scene, tmp_path):
    pytest.importorskip("distributed", reason="the batch extra (dask.distributed) is part of ./setup.sh test")
    s = Session()
    ref = run_batch(s, scene / "g.yaml", **_sweep_kw(tmp_path, scene, "inproc"))
    res = run_batch(s, scene / "g.yaml", executor="dask", workers=2, **_sweep_kw(tmp_path, scene, "dask"))
    assert ref.count("done") == res.count("done") == 6, res.table()
    assert res.workers == 2
    assert all(r.worker and not r.worker.endswith(f":{os.getpid()}") for r in res.results)  # ran in the workers
    _same_files(tmp_path, "inproc", "dask", 6)


@pytest.mark.slow  # spawns two processes (~10 s); the Dask test runs the same worker code by default
def test_process_pool_matches_in_process(scene, tmp_path):
    s = Session()
    kw = _sweep_kw(tmp_path, scene, "inproc")
    kw["sweeps"] = [f"cutout.path={scene}/cutouts/c[0-1].png", "light.azimuth=-60:60:60"]
    ref = run_batch(s, scene / "g.yaml", **kw)
    kw["outputs"] = {k: v.replace("inproc", "pool") for k, v in kw["outputs"].items()}
    res = run_batch(s, scene / "g.yaml", executor="processes", workers=2, **kw)
    assert ref.count("done") == res.count("done") == 4, res.table()
    assert all(not r.worker.endswith(f":{os.getpid()}") for r in res.results)
    _same_files(tmp_path, "inproc", "pool", 4)


# -- docs/batch.md: its commands run --------------------------------------------------

DOC = os.path.join(os.path.dirname(__file__), "..", "docs", "batch.md")
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _blocks(lang):
    import re

    return re.findall(rf"```{lang}\n(.*?)```", open(DOC).read(), re.S)


def test_batch_doc_commands_run(tmp_path, monkeypatch, capsys):
    """The doc's `pixgraph batch` commands, manifest and Python block, in a folder with
    the repo's graphs and two cutouts (4 light samples instead of 48, for time)."""
    import shlex
    import shutil

    monkeypatch.chdir(tmp_path)
    os.symlink(os.path.join(REPO, "graphs"), tmp_path / "graphs")
    (tmp_path / "cutouts").mkdir()
    for f in ("figure.png", "figure_far.png"):
        shutil.copy(os.path.join(REPO, "graphs", "assets", f), tmp_path / "cutouts" / f)
    (csv_text,) = _blocks("csv")
    (tmp_path / "shots.csv").write_text(csv_text)
    commands = [c.strip() for block in _blocks("sh") for c in block.splitlines()
                if c.strip().startswith("pixgraph batch") and "--scheduler" not in c]
    assert len(commands) == 3
    reg = Registry.discover()
    for cmd in commands:
        argv = shlex.split(cmd)[1:] + ["--set", "shadow.samples=4", "--no-disk-cache"]
        assert main(argv, reg) == 0, capsys.readouterr()
    out = capsys.readouterr().out
    assert "2 done, 0 skipped" in out and "3 done, 0 skipped" in out and "6 done, 0 skipped" in out
    names = sorted(os.listdir(tmp_path / "composites"))
    assert names == sorted(f"{n}.png{e}" for n in ("figure", "figure_far", "hero_left", "hero_right", "far")
                           for e in ("", ".json"))
    assert len(os.listdir(tmp_path / "sweep")) == 12 and (tmp_path / "sweep" / "az-60_el30.png").is_file()
    meta = json.loads((tmp_path / "composites" / "hero_right.png.json").read_text())
    assert meta["params"]["light.azimuth"] == 45 and meta["row"] == "hero_right"
    # the Python block
    (py,) = _blocks("python")
    exec(compile(py.replace('"shadow.samples": 16', '"shadow.samples": 4'), "batch.md python", "exec"), {})
    out = capsys.readouterr().out
    assert "2 done" in out and "left done" in out and (tmp_path / "composites" / "right.png").is_file()


def test_rows_never_write_over_their_inputs(scene, tmp_path):
    """Manifest and sweep files are the user's (allowed outside the graph's folder),
    but an output template that lands on a row's own input fails that row."""
    (tmp_path / "cut").mkdir()
    src = (scene / "cutouts" / "c1.png").read_bytes()
    (tmp_path / "cut" / "c1.png").write_bytes(src)
    res = run_batch(Session(), scene / "g.yaml", sweeps=[f"cutout.path={tmp_path}/cut/*.png"],
                          outputs={"final": str(tmp_path / "cut" / "{stem}.png")})
    assert [r.status for r in res.results] == ["failed"] and "would write over" in res.results[0].error
    assert (tmp_path / "cut" / "c1.png").read_bytes() == src


# -- rows that differ only downstream share what is upstream -----------------------------------


def _ran(out, n):
    return [json.loads((out / f"{i:04d}.exr.json").read_text())["ran"] for i in range(n)]


@pytest.mark.parametrize("share", [True, False])
def test_rows_share_upstream_even_past_the_cache_limit(scene, tmp_path, share):
    """Two cutouts x three azimuths, the cutouts interleaved by a manifest, with a memory
    cache that holds about one 64x64 result: grouped, each cutout's upstream (load,
    heights, camera, photo) is computed once and held for its three rows; ungrouped,
    the byte limit makes every row compute it again. Pixels are the same either way."""
    rows = [{"cutout.path": f"{scene}/cutouts/c{k}.png", "light.azimuth": a} for a in (-60, 0, 60) for k in (0, 1)]
    out = tmp_path / "out"
    s = Session(cache_bytes=100_000)
    res = run_batch(s, scene / "g.yaml", rows=rows, outputs={"final": str(out / "{index:04d}.exr")}, share=share)
    assert s.memory.limit_bytes == 100_000  # the pins' extra room is given back
    assert res.count("done") == 6 and res.groups == (2 if share else 6)
    ran = _ran(out, 6)
    upstream = {"cutout", "photo", "fg_h", "bg_h", "cam"}
    computed = sum(len(upstream & set(r)) for r in ran)
    if share:
        assert computed <= 2 * 5  # at most once per group (cutout), in the group's first row
        assert sum("cutout" in r for r in ran) == 2 and sum("fg_h" in r for r in ran) == 2
        assert all(set(r) == {"light", "shadow", "comp"} for r in ran[2:])  # rows 2..5: only what the light changes
    else:
        assert computed >= 5 * 6 - 6  # the tiny cache kept next to nothing
    for i, row in enumerate(rows):
        single = Session().run(scene / "g.yaml", outputs=["final"], params=row)["final"]
        assert np.array_equal(_pixels(out / f"{i:04d}.exr"), single), f"row {i}"


def test_grouping_follows_the_fastest_varying_param(scene):
    from pixgraph_batch.work import group_items

    s = Session()
    g = s.load(scene / "g.yaml")
    rows = B.sweep_rows([("cutout.path", [f"{scene}/cutouts/c{k}.png" for k in range(3)]),
                         ("light.azimuth", [0, 10, 20, 30]), ("light.elevation", [20, 40])])
    items = B.make_items(g, rows, s.registry, {"final": "/tmp/x/{index}.png"})
    groups = group_items(g, items)
    # azimuth varies most; elevation is on the same node (light): groups are the cutouts
    assert [len(x) for x in groups] == [8, 8, 8]
    assert all(len({it.params["cutout.path"] for it in grp}) == 1 for grp in groups)
    # a shared (--set) value changes nothing; one row, one group
    assert len(group_items(g, items[:1])) == 1
