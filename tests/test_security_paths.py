"""The path policy: every way a graph file could read or write outside its
folder is refused with exit 2 and one line naming file, node and param, and
allowed once the user allows that folder (``--allow-path``)."""
import os
import pathlib

import numpy as np
import pytest

from pixgraph.cli import main
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
