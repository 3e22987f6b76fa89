"""A user's bad inputs: each is exit code 2 and one line naming the file and the node,
from `pixgraph validate` (file headers, before anything runs) where a header shows
it, and from `pixgraph run` always; nothing crashes."""
import numpy as np
import pytest

from pixgraph import cli
from pixgraph_nodes.ops.imageio import write_image

GRAPH = """pixgraph: 1
nodes:
  cutout: {type: pixgraph.LoadImage, params: {path: CUTOUT}}
  photo:  {type: pixgraph.LoadImage, params: {path: photo.png}}
  cam:    {type: pixgraph.Camera, inputs: {image: photo.image}, params: {hfov: 50, horizon: 20, CAMSIZE}}
  place:
    type: pixgraph.PlaceCutout
    inputs: {cutout: cutout.image, background: photo.image INPUTS}
    params: {foot: FOOT, scale: 1.0}
  bg_h:   {type: pixgraph.BackgroundHeight, inputs: {camera: cam.camera}, params: {kind: back_wall, junction_row: 70}}
  light:  {type: pixgraph.Light, inputs: {camera: cam.camera, mask: place.alpha}, params: {radius: 0.2}}
  shadow:
    type: pixgraph.SoftShadow
    inputs: {mask: place.alpha, fg_height: place.height, bg_height: bg_h.height, light: light.light, camera: cam.camera}
    params: {samples: 4}
  comp: {type: pixgraph.Composite, inputs: {background: photo.image, cutout: place.image, alpha: place.alpha, shadow: shadow.darkness}}
outputs: {final: comp.image}
"""

EXTRA = {
    "mask": "  mask: {type: pixgraph.LoadMask, params: {path: MASK}}\n",
    "height": "  fg_h: {type: pixgraph.LoadPixelHeight, params: {path: HEIGHT}}\n",
}


def _rgba(h, w, alpha=1.0):
    a = np.zeros((h, w, 4), np.float32)
    a[2:-2, 2:-2] = [0.5 * alpha, 0.3 * alpha, 0.2 * alpha, alpha]
    return a


def _scene(tmp_path, cutout="cut.png", foot=(60, 100), mask=None, height=None, camsize=""):
    write_image(tmp_path / "photo.png", np.full((120, 160, 3), 0.5, np.float32))
    write_image(tmp_path / "cut.png", _rgba(40, 20))
    text = GRAPH.replace("CUTOUT", cutout).replace("FOOT", str(list(foot)))
    text = text.replace(", CAMSIZE", f", {camsize}" if camsize else "")
    inputs = ""
    if mask:
        text = text.replace("nodes:\n", "nodes:\n" + EXTRA["mask"].replace("MASK", mask))
        inputs += ", mask: mask.mask"
    if height:
        text = text.replace("nodes:\n", "nodes:\n" + EXTRA["height"].replace("HEIGHT", height))
        inputs += ", height: fg_h.height"
    text = text.replace(" INPUTS", inputs)
    g = tmp_path / "user.yaml"
    g.write_text(text)
    return g


def _cases(tmp_path):
    """(name, graph kwargs, make files, file named, node named, caught by validate)."""
    def png(name, arr):
        return lambda: write_image(tmp_path / name, arr)

    def npy(name, arr):
        return lambda: np.save(tmp_path / name, arr)

    def raw(name, data):
        return lambda: (tmp_path / name).write_bytes(data)

    nan_h = np.zeros((40, 20), np.float32)
    nan_h[5, 5] = np.nan
    return [
        ("jpeg cutout, no alpha", dict(cutout="cut.jpg"), png("cut.jpg", np.full((40, 20, 3), 0.5, np.float32)),
         "cut.jpg", "place", True),
        ("rgb png cutout", dict(cutout="rgb.png"), png("rgb.png", np.full((40, 20, 3), 0.5, np.float32)),
         "rgb.png", "place", True),
        ("1x1 cutout", dict(cutout="dot.png"), png("dot.png", np.ones((1, 1, 4), np.float32)), "dot.png", "place", True),
        ("empty alpha", dict(cutout="empty.png"), png("empty.png", np.zeros((40, 20, 4), np.float32)),
         "empty.png", "place", False),
        ("cutout fully outside the canvas", dict(foot=(900, 900)), None, "cut.png", "place", True),
        ("cutout outside, above the canvas", dict(foot=(60, -5)), None, "cut.png", "place", True),
        ("mask of another size", dict(cutout="cut.jpg", mask="m.png"),
         lambda: (png("cut.jpg", np.full((40, 20, 3), 0.5, np.float32))(), png("m.png", np.ones((30, 30), np.float32))()),
         "m.png", "place", True),
        ("NaN in the mask", dict(cutout="cut.jpg", mask="m.npy"),
         lambda: (png("cut.jpg", np.full((40, 20, 3), 0.5, np.float32))(), npy("m.npy", nan_h)()),
         "m.npy", "mask", True),
        ("empty mask for an RGB cutout", dict(cutout="cut.jpg", mask="m0.npy"),
         lambda: (png("cut.jpg", np.full((40, 20, 3), 0.5, np.float32))(), npy("m0.npy", np.zeros((40, 20)))()),
         "m0.npy", "place", False),
        ("NaN pixel height", dict(height="h.npy"), npy("h.npy", nan_h), "h.npy", "fg_h", True),
        ("pixel height of another picture", dict(height="h2.npy"), npy("h2.npy", np.zeros((40, 40), np.float32)),
         "h2.npy", "place", True),
        ("pixel height not an image", dict(height="h.exr"), raw("h.exr", b"not an exr"), "h.exr", "fg_h", True),
        ("corrupt cutout file", dict(cutout="bad.png"), raw("bad.png", b"\x89PNG broken"), "bad.png", "cutout", True),
        ("camera size typed and wrong", dict(camsize="width: 512, height: 512"), None, "photo.png", "cam", True),
    ]


CASE_NAMES = [c[0] for c in _cases(None)]


@pytest.mark.parametrize("name", CASE_NAMES)
def test_bad_input_is_one_line_naming_file_and_node(name, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    case = next(c for c in _cases(tmp_path) if c[0] == name)
    _, kwargs, make, file, node, static = case
    graph = _scene(tmp_path, **kwargs)
    if make:
        make()
    for command in (["validate"], ["run", "--no-disk-cache", "-q"]):
        rc = cli.main([command[0], str(graph), *command[1:]])
        out, err = capsys.readouterr()
        lines = err.strip().splitlines()
        if command[0] == "validate" and not static:
            assert rc == 0, err      # only the pixels show it: `run` must catch it
            continue
        assert rc == 2, (command, err)
        assert len(lines) == 1, err
        assert file in lines[0] and f"node '{node}'" in lines[0], lines[0]


def test_good_scene_validates_and_runs(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    graph = _scene(tmp_path)
    assert cli.main(["validate", str(graph)]) == 0
    assert cli.main(["run", str(graph), "--no-disk-cache", "-q", "-o", f"final={tmp_path / 'o.png'}"]) == 0


def test_size_problem_at_run_time_names_the_files(tmp_path, capsys, monkeypatch):
    """An old-style graph (cutout at the plate's size) given a crop: validate and run
    both name the two files, not only internal ports."""
    monkeypatch.chdir(tmp_path)
    write_image(tmp_path / "photo.png", np.full((120, 160, 3), 0.5, np.float32))
    write_image(tmp_path / "small.png", _rgba(40, 20))
    (tmp_path / "g.yaml").write_text("""pixgraph: 1
nodes:
  cutout: {type: pixgraph.LoadImage, params: {path: small.png}}
  photo:  {type: pixgraph.LoadImage, params: {path: photo.png}}
  comp: {type: pixgraph.Composite, inputs: {background: photo.image, cutout: cutout.image, alpha: cutout.alpha}}
outputs: {final: comp.image}
""")
    for argv in (["validate", "g.yaml"], ["run", "g.yaml", "--no-disk-cache", "-q"]):
        assert cli.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "small.png" in err[0] and "photo.png" in err[0] and "node 'comp'" in err[0], err
