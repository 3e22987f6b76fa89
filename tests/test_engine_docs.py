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


REPO = os.path.dirname(DOCS)
EMBEDDING_BLOCKS = _python_blocks(os.path.join(DOCS, "embedding.md"))


def test_embedding_has_the_documented_blocks():
    assert len(EMBEDDING_BLOCKS) == 4


@pytest.mark.parametrize("index", range(len(EMBEDDING_BLOCKS)))
def test_embedding_examples_run(index, monkeypatch, capsys):
    monkeypatch.chdir(REPO)  # blocks name graphs/... relative to the repository root
    exec(compile(EMBEDDING_BLOCKS[index], f"embedding.md block {index}", "exec"), {})
    if index == 0:
        out = capsys.readouterr().out
        assert "soften" in out and "params.sigma changed" in out


def test_tutorial_bind_example_runs_and_prints_what_it_says(monkeypatch, capsys):
    text = open(os.path.join(DOCS, "tutorial.md")).read()
    blocks = re.findall(r"```python\n(.*?)```\n\n```\n(.*?)```", text, re.S)
    code, printed = next((c, p) for c, p in blocks if "bind=" in c)
    monkeypatch.chdir(REPO)
    exec(compile(code, "tutorial.md bind example", "exec"), {})
    assert capsys.readouterr().out == printed


def test_nodes_md_is_the_generated_reference_whole():
    """docs/nodes.md is exactly what 'pixgraph nodes --markdown' prints for the
    installed nodes: every section, the index and the port types, nothing stale."""
    from pixgraph.cli import main

    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["nodes", "--markdown"]) == 0
    text = open(os.path.join(DOCS, "nodes.md")).read()
    assert buf.getvalue() == text, "docs/nodes.md is stale: run 'pixgraph nodes --markdown > docs/nodes.md'"
    assert text.count("\n## pixgraph.") == len(Registry.discover()) >= 28
    assert "| Mask | Image | float32 (H, W) coverage in [0, 1] | written by `-o` |" in text


@pytest.mark.parametrize("type_id", ENGINE_NODES)
def test_nodes_md_is_up_to_date_for_engine_nodes(type_id):
    reg = Registry.discover()
    text = open(os.path.join(DOCS, "nodes.md")).read()
    section = reference.markdown_section(reg.get(type_id))
    assert section in text, f"docs/nodes.md is stale for {type_id}: run 'pixgraph nodes --markdown > docs/nodes.md'"
