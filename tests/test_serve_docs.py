"""docs/server.md's Python client example runs against a real ``pixgraph serve``."""
import os
import re

from PIL import Image

from pixgraph import fileio
from pixgraph.registry import Registry
from serve_helpers import REPO, copy_scene, running_server


def test_server_md_client_example(tmp_path, monkeypatch, capsys):
    text = open(os.path.join(REPO, "docs", "server.md")).read()
    (code,) = re.findall(r"```python\n(.*?)```", text, re.S)
    (expected,) = re.findall(r"It prints\n\n```text\n(.*?)```", text, re.S)
    graph = copy_scene(str(tmp_path / "scene"))
    monkeypatch.chdir(tmp_path)
    with running_server(graph) as (url, _):
        import httpx

        httpx.post(url + "/api/run", json={}, timeout=120).raise_for_status()   # "after a first run"
        assert 'URL = "http://127.0.0.1:8765"' in code
        exec(compile(code.replace("http://127.0.0.1:8765", url), "server.md", "exec"), {})
    assert capsys.readouterr().out == expected
    assert Image.open(tmp_path / "final.png").size == (512, 512)
    saved = fileio.load(tmp_path / "scene" / "wall_corner_edited.yaml", Registry.discover())
    assert saved.nodes["light"].params["azimuth"] == 40
