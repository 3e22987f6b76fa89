"""The documentation's examples run, and docs/nodes.md matches the declarations of the engine's nodes."""
import os
import re

import pytest

from pixgraph import reference
from pixgraph.registry import Registry

DOCS = os.path.join(os.path.dirname(__file__), "..", "docs")
ENGINE_NODES = ["pixgraph.Constant", "pixgraph.GaussianBlur", "pixgraph.LoadImage", "pixgraph.Merge",
                "pixgraph.SaveImage"]


def _python_blocks(path):
    return re.findall(r"```python\n(.*?)```", open(path).read(), re.S)


@pytest.mark.parametrize("index", [0, 1])
def test_embedding_examples_run(index, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    blocks = _python_blocks(os.path.join(DOCS, "embedding.md"))
    assert len(blocks) == 2
    exec(compile(blocks[index], f"embedding.md block {index}", "exec"), {})
    if index == 0:
        out = capsys.readouterr().out
        assert "soften" in out and "params.sigma changed" in out


@pytest.mark.parametrize("type_id", ENGINE_NODES)
def test_nodes_md_is_up_to_date_for_engine_nodes(type_id):
    reg = Registry.discover()
    text = open(os.path.join(DOCS, "nodes.md")).read()
    section = reference.markdown_section(reg.get(type_id))
    assert section in text, f"docs/nodes.md is stale for {type_id}: run 'pixgraph nodes --markdown > docs/nodes.md'"
