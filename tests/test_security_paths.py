"""The path policy: every way a graph file could read or write outside its
folder is refused with exit 2 and one line naming file, node and param, and
allowed once the user allows that folder (``--allow-path``). Writes keep to the
folder that was checked even when a folder on the way is swapped for a symlink
before the write, and a cutout without alpha is refused wherever its alpha is used."""
import os
import pathlib
import shutil

import numpy as np
import pytest

from pixgraph import events as E
from pixgraph.cli import main
from pixgraph.engine import NodeInputError
from pixgraph.paths import PathError, PathPolicy
from pixgraph.session import Session
from pixgraph_nodes.ops.imageio import read_image, write_image

READ = """pixgraph: 1
nodes:
  load: {{type: pixgraph.LoadImage, params: {{path: {path}}}}}
outputs: {{img: load.image}}
"""
WRITE = """pixgraph: 1
nodes:
  c: {{type: pixgraph.Constant, params: {{width: 3, height: 2}}}}
  save: {{type: pixgraph.SaveImage, params: {{path: {path}}}, inputs: {{image: c.image}}}}
outputs: {{file: save.path}}
"""
ROUTES = ["absolute", "dotdot", "tilde", "symlink_file", "symlink_folder", "new_folders"]


@pytest.fixture
def world(tmp_path, monkeypatch):
    """A job folder with the graph, and an outside folder holding a file."""
    job, outside = tmp_path / "job", tmp_path / "outside"
    job.mkdir()
    (outside / "sub").mkdir(parents=True)
    write_image(outside / "secret.png", np.full((2, 3, 4), 0.5, np.float32))
    write_image(outside / "sub" / "secret.png", np.full((2, 3, 4), 0.5, np.float32))
    os.symlink(outside / "secret.png", job / "link.png")
    os.symlink(outside, job / "dirlink")
    monkeypatch.setenv("HOME", str(outside))
    monkeypatch.delenv("PIXGRAPH_ALLOW_PATHS", raising=False)
    return job, outside


def _route(route: str, outside: pathlib.Path, write: bool) -> str:
    name = "written.png" if write else "secret.png"
    return {"absolute": str(outside / name), "dotdot": f"../outside/{name}", "tilde": f"~/{name}",
            "symlink_file": "link.png", "symlink_folder": f"dirlink/{name}",
            "new_folders": "../outside/new/deeper/" + name if write else "../outside/sub/secret.png"}[route]


def _cli(capsys, *argv):
    code = main(["--quiet", *argv] if argv[0] != "run" else [argv[0], "-q", "--no-disk-cache", *argv[1:]])
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


def _graph(job, template, path):
    g = job / "g.yaml"
    g.write_text(template.format(path=repr(path).replace("'", '"') if "\\" in repr(path) else f'"{path}"'))
    return str(g)


@pytest.mark.parametrize("route", ROUTES)
@pytest.mark.parametrize("write", [False, True], ids=["read", "write"])
def test_escape_route_is_refused_then_allowed(world, capsys, route, write):
    job, outside = world
    before = sorted(p.relative_to(outside) for p in outside.rglob("*"))
    g = _graph(job, WRITE if write else READ, _route(route, outside, write))
    code, err = _cli(capsys, "run", g)
    assert code == 2, err
    assert len(err) == 1 and len(err[0]) <= 300 and "Traceback" not in err[0]
    assert err[0].startswith(g + ":") and ("node 'save'" if write else "node 'load'") in err[0]
    assert "param 'path'" in err[0] and "outside the allowed folders" in err[0]
    # nothing was written or created outside, and the secret is unchanged
    assert sorted(p.relative_to(outside) for p in outside.rglob("*")) == before
    np.testing.assert_allclose(read_image(outside / "secret.png")[1], 0.5, atol=0.01)
    # validate refuses it too (before anything runs)
    assert _cli(capsys, "validate", g)[0] == 2
    # allowed once the user allows the outside folder
    code, err = _cli(capsys, "run", g, "--allow-path", str(outside))
    assert code == 0, err
    if write:
        target = {"symlink_file": outside / "secret.png",
                  "new_folders": outside / "new" / "deeper" / "written.png"}.get(route, outside / "written.png")
        assert read_image(target)[0].shape == (2, 3, 4)


@pytest.mark.parametrize("bad", ["a\0.png", "~/bashrc\0.png", "a\n.png", "a\x1b[2J.png", "a\x7f.png"])
@pytest.mark.parametrize("write", [False, True], ids=["read", "write"])
def test_nul_and_control_characters_are_refused_even_when_allowed(world, capsys, bad, write):
    job, outside = world
    g = _graph(job, WRITE if write else READ, bad)
    for cmd in ("validate", "run"):
        code, err = _cli(capsys, cmd, g, "--allow-path", str(outside), "--allow-path", str(job))
        assert code == 2 and len(err) == 1 and len(err[0]) <= 300
        assert "param 'path'" in err[0] and ("NUL" in err[0] or "control character" in err[0])
    assert sorted(os.listdir(job)) == ["dirlink", "g.yaml", "link.png"]
    assert not (outside / "bashrc").exists()


def test_inside_the_graph_folder_is_allowed_and_symlinks_are_resolved(world, capsys):
    job, outside = world
    write_image(job / "here.png", np.full((2, 3, 4), 0.25, np.float32))
    os.symlink(job / "here.png", job / "inner_link.png")
    g = _graph(job, READ, "inner_link.png")
    assert _cli(capsys, "run", g)[0] == 0
    g = _graph(job, WRITE, "out/sub/x.png")
    assert _cli(capsys, "run", g)[0] == 0 and (job / "out" / "sub" / "x.png").is_file()


def test_writing_over_an_input_of_the_same_run_is_refused(world, capsys):
    job, _ = world
    write_image(job / "in.png", np.full((2, 3, 4), 0.25, np.float32))
    g = job / "g.yaml"
    g.write_text("""pixgraph: 1
nodes:
  load: {type: pixgraph.LoadImage, params: {path: in.png}}
  save: {type: pixgraph.SaveImage, params: {path: ./in.png}, inputs: {image: load.image}}
outputs: {file: save.path}
""")
    code, err = _cli(capsys, "run", str(g))
    assert code == 2 and "node 'save'" in err[0] and "would write over" in err[0]
    # nor may -o (the user's own path) overwrite the input or the graph file
    (job / "g2.yaml").write_text(READ.format(path="in.png"))
    for target in (job / "in.png", job / "g2.yaml"):
        code, err = _cli(capsys, "run", str(job / "g2.yaml"), "-o", f"img={target}")
        assert code == 2 and "would write over" in err[0]
    np.testing.assert_allclose(read_image(job / "in.png")[1], 0.25, atol=0.01)


def test_cli_output_and_set_paths_are_the_users(world, capsys):
    job, outside = world
    write_image(job / "mine.png", np.zeros((1, 1, 4), np.float32))
    (job / "g.yaml").write_text(READ.format(path="mine.png"))
    code, err = _cli(capsys, "run", str(job / "g.yaml"), "--set", f"load.path={outside / 'secret.png'}",
                     "-o", f"img={outside / 'o' / 'copy.png'}")
    assert code == 0, err
    assert (outside / "o" / "copy.png").is_file()
    # only that one file: its sibling is still refused
    (job / "g.yaml").write_text(READ.format(path="../outside/sub/secret.png"))
    assert _cli(capsys, "run", str(job / "g.yaml"), "--set", f"load.path={outside / 'secret.png'}")[0] == 0
    assert _cli(capsys, "run", str(job / "g.yaml"))[0] == 2


def test_policy_api_and_strict_mode(world, monkeypatch):
    job, outside = world
    p = PathPolicy([job])
    with pytest.raises(PathError, match="outside the allowed folders") as e:
        p.check_read(job / "link.png", node="n", param="path")  # resolves to outside/secret.png
    assert e.value.node == "n" and e.value.field == "params.path"
    assert p.check_write(job / "x" / "y.png") == pathlib.Path(os.path.realpath(job)) / "x" / "y.png"
    with pytest.raises(PathError, match="not a regular file"):
        PathPolicy([outside]).check_read(outside / "sub")
    monkeypatch.setenv("PIXGRAPH_ALLOW_PATHS", os.pathsep.join([str(outside), "/nonexistent"]))
    assert PathPolicy([job]).check_read(outside / "secret.png").name == "secret.png"
    with pytest.raises(PathError):  # strict: the environment is not consulted
        PathPolicy([job], strict=True).check_read(outside / "secret.png")
    # a built graph (no file) has its base_dir as its folder
    s = Session(strict_paths=True)
    b = s.builder(base_dir=str(job))
    b.add("pixgraph.LoadImage", "load", path=str(outside / "secret.png"))
    b.output("img", "load.image")
    with pytest.raises(PathError):
        s.run(b.build())
    s = Session(strict_paths=True, allow_paths=[outside])
    assert s.run(b.build())["img"].shape == (2, 3, 4)


# -- a folder swapped for a symlink between the check and the write ----------------------

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def _tree(root):
    return sorted((os.path.relpath(os.path.join(d, n), root), os.path.getsize(os.path.join(d, n)))
                  for d, _, files in os.walk(root) for n in files)


@pytest.mark.parametrize("swapped", ["out", "out/sub"])
@pytest.mark.parametrize("ext", ["png", "npy", "exr"])
def test_a_folder_swapped_for_a_symlink_after_the_check_is_not_written_through(world, swapped, ext):
    job, outside = world
    (job / "out" / "sub").mkdir(parents=True)
    before = _tree(outside)
    s = Session(disk_cache=None)
    b = s.builder(base_dir=str(job))
    b.add("pixgraph.Constant", "c", width=3, height=2)
    b.add("pixgraph.SaveImage", "save", path=f"out/sub/x.{ext}")
    b.connect("c.image", "save.image")
    b.output("file", "save.path")
    g = b.build()
    target = outside if swapped == "out" else outside / "sub"

    def swap(ev):  # the plan checked out/sub; now the attacker's symlink takes its place
        if isinstance(ev, E.NodeStarted) and ev.node_id == "save":
            shutil.rmtree(job / swapped)
            os.symlink(target, job / swapped)

    with pytest.raises(NodeInputError) as e:
        s.run(g, on_event=swap)
    msg = str(e.value)
    assert "node 'save'" in msg and "now a symlink or not a folder" in msg and "nothing was written" in msg
    assert _tree(outside) == before  # 0 files written outside, no temporary left
    # the same graph, unswapped, writes where it was checked to
    os.unlink(job / swapped)
    (job / "out" / "sub").mkdir(parents=True, exist_ok=True)
    assert s.run(g)["file"] == str(job / "out" / "sub" / f"x.{ext}")
    assert (job / "out" / "sub" / f"x.{ext}").is_file() and _tree(outside) == before


def test_a_symlinked_folder_inside_the_graph_folder_is_written_through_as_checked(world):
    job, outside = world
    (job / "real").mkdir()
    os.symlink(job / "real", job / "alias")
    s = Session(disk_cache=None)
    b = s.builder(base_dir=str(job))
    b.add("pixgraph.Constant", "c", width=3, height=2)
    b.add("pixgraph.SaveImage", "save", path="alias/new/y.png")
    b.connect("c.image", "save.image")
    b.output("file", "save.path")
    out = s.run(b.build())["file"]
    assert out == str(job / "alias" / "new" / "y.png")  # the path as the graph names it
    assert read_image(job / "real" / "new" / "y.png")[0].shape == (2, 3, 4)
    assert sorted(os.listdir(job / "real" / "new")) == ["y.png"]  # no temporary left


# -- a cutout without alpha: refused wherever its alpha is used ----------------------------

def test_a_jpeg_as_the_cutout_of_the_example_graph_is_refused(capsys, tmp_path):
    graph = os.path.join(REPO, "graphs", "wall_corner_shadow.yaml")
    before = _tree(os.path.join(REPO, "graphs"))
    messages = []
    for argv in (["run", graph, "-q", "--no-disk-cache", "--set", "cutout.path=assets/room_ground.jpg",
                  "-o", f"final={tmp_path / 'final.png'}"],
                 ["validate", graph, "-q", "--set", "cutout.path=assets/room_ground.jpg"]):
        code = main(argv)
        err = capsys.readouterr().err.strip().splitlines()
        assert code == 2 and len(err) == 1 and len(err[0]) <= 300, err
        assert err[0].startswith(graph + ":") and "node 'fg_h'" in err[0] and "input 'mask'" in err[0]
        assert "'assets/room_ground.jpg' (node 'cutout')" in err[0] or "room_ground.jpg' (node 'cutout')" in err[0]
        messages.append(err[0])
    assert not (tmp_path / "final.png").exists() and _tree(os.path.join(REPO, "graphs")) == before
    # PlaceCutout's own refusal of the same file, word for word
    (tmp_path / "g.yaml").write_text(f"""pixgraph: 1
nodes:
  cutout: {{type: pixgraph.LoadImage, params: {{path: {os.path.join(REPO, 'graphs', 'assets', 'room_ground.jpg')}}}}}
  place: {{type: pixgraph.PlaceCutout, inputs: {{cutout: cutout.image, background: cutout.image}}}}
outputs: {{img: place.image}}
""")
    assert main(["validate", str(tmp_path / "g.yaml"), "-q", "--allow-path", REPO]) == 2
    placed = capsys.readouterr().err.strip()
    tail = placed[placed.index("has no alpha channel"):]
    assert all(m.endswith(tail) for m in messages) and "(3 channels)" in tail
    # the JPEG as the photo (its image, not its alpha) is fine
    assert main(["validate", graph, "-q", "--set", "photo.path=assets/room_ground.jpg"]) == 0


@pytest.mark.parametrize("writer", ["image", "data", "exr_channels"])
def test_every_writer_keeps_to_the_folder_that_was_checked(world, writer):
    from pixgraph.paths import WritePath
    from pixgraph_nodes.ops.imageio import ImageFileError, write_data, write_exr_channels

    job, outside = world
    (job / "out").mkdir()
    named = str(job / "out" / "new" / "m.exr")
    checked = WritePath(named, os.path.realpath(named))  # as the engine hands it to a node
    os.rmdir(job / "out")
    os.symlink(outside, job / "out")  # swapped after the check
    before = _tree(outside)
    a = np.full((2, 3), 0.25, np.float32)
    write = {"image": lambda p: write_image(p, a), "data": lambda p: write_data(p, a),
             "exr_channels": lambda p: write_exr_channels(p, {"x": a, "y": a})}[writer]
    with pytest.raises(ImageFileError, match="now a symlink or not a folder"):
        write(checked)
    assert _tree(outside) == before and not (outside / "new").exists()
    # a plain path (the user's own -o) goes where it points at the time of the write
    write(named)
    assert (outside / "new" / "m.exr").is_file()


ENTER_ONLY = """
import os, sys, tempfile
import numpy as np
from pixgraph.paths import WritePath
from pixgraph_nodes.ops.imageio import write_image
with tempfile.TemporaryDirectory() as warm:  # load the PNG plugin while the installation is readable
    write_image(os.path.join(warm, "w.png"), np.zeros((2, 2, 4), np.float32))
if os.geteuid() == 0:
    os.setgid(65534)
    os.setuid(65534)  # nobody: the folder above may be entered, not listed
p = sys.argv[1]
write_image(WritePath(p, p), np.zeros((2, 2, 4), np.float32))
print("written")
"""


def test_a_folder_that_may_be_entered_but_not_listed_is_written_through():
    """Like a path walk, the writer needs only search permission on the folders above
    (``O_PATH``): a home folder of mode 0711 must not stop a write below it."""
    import subprocess
    import sys
    import tempfile

    top = tempfile.mkdtemp(prefix="pixgraph-enter-only-", dir="/tmp")
    try:
        os.chmod(top, 0o711)
        outer, inner = os.path.join(top, "outer"), os.path.join(top, "outer", "inner")
        os.makedirs(inner)
        os.chmod(inner, 0o777)
        os.chmod(outer, 0o311 if os.geteuid() else 0o711)  # search, no read: for the user who writes
        target = os.path.join(inner, "a.png")
        p = subprocess.run([sys.executable, "-c", ENTER_ONLY, target], capture_output=True, text=True, timeout=120)
        assert p.returncode == 0 and "written" in p.stdout, p.stderr[-500:]
        assert os.path.getsize(target) > 0
    finally:
        os.chmod(os.path.join(top, "outer"), 0o755)
        shutil.rmtree(top)


def test_folder_write_replace_checks_then_renames_and_leaves_nothing_on_failure(tmp_path):
    from pixgraph.paths import Folder
    (tmp_path / "out").mkdir()
    (tmp_path / "victim").write_text("ORIGINAL")
    with Folder.at(str(tmp_path / "out")) as folder:
        folder.write_replace("a.txt", b"one", ".a.tmp")
        assert (tmp_path / "out" / "a.txt").read_bytes() == b"one"

        def refuse(tmp):
            assert (tmp_path / "out" / tmp).read_bytes() == b"two"      # written before the check
            raise ValueError("no")
        with pytest.raises(ValueError):
            folder.write_replace("a.txt", b"two", ".a.tmp", check=refuse)
        assert (tmp_path / "out" / "a.txt").read_bytes() == b"one"
        # a symlink planted at the temporary's name is neither written through nor removed as if ours
        os.symlink(tmp_path / "victim", tmp_path / "out" / ".b.tmp")
        with pytest.raises(FileExistsError):
            folder.write_replace("b.txt", b"three", ".b.tmp")
    assert (tmp_path / "victim").read_text() == "ORIGINAL"
    assert sorted(os.listdir(tmp_path / "out")) == [".b.tmp", "a.txt"]
