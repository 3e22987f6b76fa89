"""docs/server.md's Python client example runs against a real ``pixgraph serve``
(with its per-launch token), and its option list matches ``pixgraph serve --help``."""
import os
import re

from PIL import Image

from pixgraph import fileio
from pixgraph.registry import Registry
from serve_helpers import REPO, copy_scene, start_server

DOC = os.path.join(REPO, "docs", "server.md")


def test_server_md_client_example(tmp_path, monkeypatch, capsys):
    text = open(DOC).read()
    (code,) = re.findall(r"```python\n(.*?)```", text, re.S)
    (expected,) = re.findall(r"It prints\n\n```text\n(.*?)```", text, re.S)
    graph = copy_scene(str(tmp_path / "scene"))
    monkeypatch.chdir(tmp_path)
    with start_server(graph) as (url, token, _):
        import httpx

        httpx.post(url + "/api/run", json={}, headers={"X-Pixgraph-Token": token},
                   timeout=120).raise_for_status()   # "after a first run"
        assert 'URL = "http://127.0.0.1:8765"' in code and 'TOKEN = "3kX...Q"' in code
        code = code.replace("http://127.0.0.1:8765", url).replace("3kX...Q", token)
        exec(compile(code, "server.md", "exec"), {})
    assert capsys.readouterr().out == expected
    assert Image.open(tmp_path / "final.png").size == (512, 512)
    saved = fileio.load(tmp_path / "scene" / "wall_corner_edited.yaml", Registry.discover())
    assert saved.nodes["light"].params["azimuth"] == 40


def test_server_md_names_every_option():
    import argparse

    from pixgraph_serve.cli import add_arguments

    text = open(DOC).read()
    start = text[text.index("## Start it"):text.index("## The page")]
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    options = {o for a in parser._actions for o in a.option_strings if o.startswith("--")} - {"--help"}
    assert len(options) == 8 and options <= set(re.findall(r"`(--[a-z][a-z-]+)", start)), options


def test_server_md_limits_are_the_codes():
    # numbers the docs repeat from the code: a changed limit must change the docs too
    from pixgraph_serve import history
    from pixgraph_serve.runs import Renders
    text = open(DOC).read()
    assert f"at most {history.MAX_STEP_ACTIONS} actions" in text
    assert f"at most {Renders().max_clients} clients" in text


def test_server_md_elevation_slider_ends_are_what_the_page_is_told(tmp_path):
    """The elevation slider's ends docs/server.md states (controls placement, then
    shadow_tip) are /api/scene's ``elevation_range`` in each placement (the controls
    one starts at the light's ``elevation_min``, not at the param's -90)."""
    from pixgraph_serve import app as serve_app
    from pixgraph_serve import scene
    from pixgraph_serve.state import ServeState
    text = open(DOC).read()
    para = text[text.index("The elevation slider spans"):text.index("The elevation is always")]
    stated = [[float(a), float(b)] for a, b in re.findall(r"(-?\d+(?:\.\d+)?) to (-?\d+(?:\.\d+)?)°", para)]
    st = ServeState(copy_scene(str(tmp_path)))
    serve_app.apply_edits(st, {"params": {"light.placement": "controls"}})
    controls = scene.describe(st)["light"]["elevation_range"]
    serve_app.apply_edits(st, {"light_tip": [230, 400]})
    tip = scene.describe(st)["light"]["elevation_range"]
    assert stated == [controls, tip], (stated, controls, tip)
