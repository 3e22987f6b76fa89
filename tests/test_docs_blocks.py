"""Every Python block and printed transcript of docs/writing-nodes.md and
docs/graph-format.md runs, and prints what the page says.

writing-nodes.md builds a pack, pixgraph-vignette, from its own blocks: here the
pack's files are written from the page into a temporary folder and registered
through an entry point object (what ``pip install -e .`` would add), and every
``$ pixgraph ...`` transcript is run through ``pixgraph.cli.main``. Times and
cache keys (which depend on the code) are compared by shape, everything else
exactly. The ``pip install``/``pip uninstall`` lines themselves are not run.
"""
import contextlib
import importlib
import io
import os
import re
import shlex
import shutil
import sys
import textwrap

import numpy as np
import pytest

from pixgraph import registry as registry_module
from pixgraph.cli import main
from pixgraph.registry import Registry

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DOCS = os.path.join(ROOT, "docs")


def _blocks(name):
    """[(language, text)] of every fenced block of a page, in order."""
    text = open(os.path.join(DOCS, name), encoding="utf-8").read()
    return [(m.group(2), textwrap.dedent(m.group(3))) for m in
            re.finditer(r"^( *)```(\w*)\n(.*?)^\1```", text, re.S | re.M)]


def _cli(argv, merged=False):
    """Exit code, stdout and stderr of ``pixgraph ARGV``; ``merged``: both in one
    stream, in the order printed (as a terminal shows them), returned as stdout."""
    out = io.StringIO()
    err = out if merged else io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), "" if merged else err.getvalue()


def _shape(text):
    """Times and hex keys replaced, so runs compare by what they say."""
    text = re.sub(r"\b[0-9a-f]{12}\b", "<key>", text)
    return re.sub(r"\d+\.\d+ s compute", "<t> s compute", text)


def _transcript(block, cwd, on_pip=None):
    """Run each ``$ pixgraph ...`` of a transcript block; returns (expected, got).
    A ``$ pip ...`` line is not run: ``on_pip(argv)`` stands in for it."""
    expected, got = [], []
    commands = re.split(r"^\$ ", block, flags=re.M)[1:]
    for cmd in commands:
        line, _, want = cmd.partition("\n")
        argv = shlex.split(line)
        if argv[0] == "pip":
            if on_pip is not None:
                on_pip(argv)
            continue
        assert argv[0] == "pixgraph", line
        grep = None
        if "|" in argv:
            grep = argv[argv.index("|") + 2]
            argv = argv[:argv.index("|")]
        if ">" in argv:
            argv = argv[:argv.index(">")]
            code, out, err = _cli(argv[1:])
            text = err
        else:
            code, text, _ = _cli(argv[1:], merged=True)
        if grep:
            text = "".join(ln + "\n" for ln in text.splitlines() if grep in ln)
        expected.append(_shape(f"$ {line}\n{want}"))
        got.append(_shape(f"$ {line}\n{text}"))
    return "".join(expected), "".join(got)


# -- writing-nodes.md ---------------------------------------------------------------

class _EntryPoint:
    """What ``pip install -e .`` of the page's pyproject.toml registers."""

    name, value, group = "vignette", "pixgraph_vignette:nodes", "pixgraph.nodes"

    def load(self):
        import importlib

        return importlib.import_module("pixgraph_vignette").nodes


@pytest.fixture
def vignette_pack(tmp_path, monkeypatch):
    blocks = _blocks("writing-nodes.md")
    py = [t for lang, t in blocks if lang == "python"]
    toml = next(t for lang, t in blocks if lang == "toml")
    assert '[project.entry-points."pixgraph.nodes"]\nvignette = "pixgraph_vignette:nodes"' in toml
    pkg = tmp_path / "pixgraph_vignette"
    pkg.mkdir()
    (pkg / "vignette.py").write_text(py[0])
    (pkg / "gain.py").write_text(next(t for t in py if t.startswith('"""vignette.Gain')))
    (pkg / "__init__.py").write_text(next(t for t in py if t.startswith('"""pixgraph-vignette')))
    (tmp_path / "demo.yaml").write_text(next(t for lang, t in blocks if lang == "yaml" and "vignette.Gain" in t))
    monkeypatch.syspath_prepend(str(tmp_path))
    for m in [m for m in sys.modules if m.startswith("pixgraph_vignette")]:
        monkeypatch.delitem(sys.modules, m)
    real = registry_module._entry_points

    def entry_points(group):
        return list(real(group)) + [_EntryPoint()]
    entry_points.__wrapped__ = real

    monkeypatch.setattr(registry_module, "_entry_points", entry_points)
    monkeypatch.setattr(Registry.discover.__func__, "__defaults__", ("pixgraph.nodes", entry_points))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("PIXGRAPH_DISK_CACHE", str(tmp_path / "cache"))
    return tmp_path


def test_writing_nodes_has_the_blocks_it_had():
    kinds = [lang for lang, _ in _blocks("writing-nodes.md")]
    assert kinds.count("python") == 6 and kinds.count("toml") == 1


def test_the_pack_installs_and_its_transcripts_print_what_the_page_says(vignette_pack, monkeypatch):
    reg = Registry.discover()
    assert {"vignette.Vignette", "vignette.Gain"} <= set(reg) and reg.errors == []
    transcripts = [t for lang, t in _blocks("writing-nodes.md") if lang == "" and t.startswith("$ p")]
    # pip install + nodes; validate/run/explain/run; explain after the impl_version bump; pip uninstall
    listing, demo, bumped, removed = transcripts[:4]
    assert listing.startswith("$ pip install -e .") and removed.startswith("$ pip uninstall -y pixgraph-vignette")
    for block in (listing, demo):
        want, got = _transcript(block, vignette_pack)
        assert got == want
    from pixgraph_nodes.ops.imageio import read_image

    img, _ = read_image(vignette_pack / "vignette.png")   # linear; the page gives the sRGB-encoded values
    srgb = 1.055 * img[..., 0].astype(np.float64) ** (1 / 2.4) - 0.055
    assert round(float(srgb[100, 160]), 2) == 0.74 and round(float(srgb[0, 0]), 2) == 0.59
    vig = vignette_pack / "pixgraph_vignette" / "vignette.py"
    vig.write_text(vig.read_text().replace('impl_version = "1"', 'impl_version = "2"'))
    # the edit keeps the file's size, and on a fast machine its second: Python would take the
    # bytecode cached at the first import as still valid (it checks size and whole-second
    # mtime) and import impl_version "1" again
    shutil.rmtree(vig.parent / "__pycache__", ignore_errors=True)
    importlib.invalidate_caches()
    for m in [m for m in sys.modules if m.startswith("pixgraph_vignette")]:
        del sys.modules[m]
    want, got = _transcript(bumped, vignette_pack)
    assert got == want

    def uninstall(argv):  # the entry point goes away
        real = registry_module._entry_points.__wrapped__
        monkeypatch.setattr(Registry.discover.__func__, "__defaults__", ("pixgraph.nodes", real))
    want, got = _transcript(removed, vignette_pack, on_pip=uninstall)
    assert got == want


def test_the_python_blocks_print_what_the_page_says(vignette_pack, capsys):
    blocks = _blocks("writing-nodes.md")
    for i, (lang, code) in enumerate(blocks):
        if lang != "python" or not ("print(" in code):
            continue
        printed = blocks[i + 1][1]
        exec(compile(code, f"writing-nodes.md block {i}", "exec"), {"__name__": f"doc_block_{i}"})
        assert capsys.readouterr().out == printed, f"block {i}"


def test_the_affects_example_is_the_lights_code():
    import inspect

    from pixgraph_nodes.light import Light

    code = next(t for lang, t in _blocks("writing-nodes.md") if lang == "python" and t.startswith("def affects"))
    source = textwrap.dedent(inspect.getsource(Light.affects))
    source = re.sub(r'    """.*?"""\n', "", source, flags=re.S)
    assert code == source


def test_broken_pack_transcripts(vignette_pack):
    pkg = vignette_pack / "pixgraph_vignette"
    (pkg / "broken.py").write_text("import scipy_not_installed  # a missing dependency\n")
    (pkg / "dup.py").write_text(textwrap.dedent('''
        from pixgraph_nodes import types as T
        from pixgraph.node import Node, node, port


        @node("pixgraph.GaussianBlur", version=1)
        class MyBlur(Node):
            """Claims a built-in id."""
            class Outputs:
                image: T.Image = port()
            def compute(self, ctx, inputs, params):
                return {}
    '''))
    init = pkg / "__init__.py"
    init.write_text(init.read_text().replace('MODULES = ["vignette", "gain"]',
                                             'MODULES = ["vignette", "gain", "broken", "dup"]'))
    blocks = [t for lang, t in _blocks("writing-nodes.md") if lang == ""]
    errors = next(t for t in blocks if t.startswith("$ pixgraph nodes > /dev/null"))
    also = next(t for t in blocks if t.startswith("$ pixgraph validate demo.yaml\ndemo.yaml:6:"))
    want, got = _transcript(errors, vignette_pack)
    assert got == want
    code, out, _ = _cli(["nodes", "--errors", "--debug"])
    traceback = next(t for t in blocks if t.startswith('  File "/tmp/tut/pack/pixgraph_vignette/broken.py"'))
    assert code == 1 and traceback.replace("/tmp/tut/pack", str(vignette_pack)) in out
    # "with vignette.py broken": a graph that uses its node sees an unknown type
    init.write_text(init.read_text().replace('MODULES = ["vignette", "gain", "broken", "dup"]',
                                             'MODULES = ["vignette", "gain"]'))
    (pkg / "vignette.py").write_text("import scipy_not_installed\n")
    for m in [m for m in sys.modules if m.startswith("pixgraph_vignette")]:
        del sys.modules[m]
    want, got = _transcript(also, vignette_pack)
    assert got == want


# -- graph-format.md ----------------------------------------------------------------

def test_graph_format_blocks(tmp_path, monkeypatch, capsys):
    blocks = _blocks("graph-format.md")
    py = [(i, t) for i, (lang, t) in enumerate(blocks) if lang == "python"]
    assert len(py) == 4
    monkeypatch.setenv("PATH", os.path.dirname(sys.executable) + os.pathsep + os.environ["PATH"])
    for i, code in py:
        if "f0.yaml" in code:  # the format-0 file shown just before it, in a folder of its own
            (tmp_path / "f0.yaml").write_text(next(t for lang, t in blocks if t.startswith("pixgraph: 0")))
            monkeypatch.chdir(tmp_path)
        else:
            monkeypatch.chdir(ROOT)
        exec(compile(code, f"graph-format.md block {i}", "exec"), {})
        out, err = capsys.readouterr()
        printed = blocks[i + 1][1]
        if "fixtures/bad" in code:  # the errors go to stderr; the full list follows the example
            listing = next(t for lang, t in blocks if t.startswith("tests/fixtures/bad/above_max.yaml"))
            listing = listing.replace("/work/main", ROOT)
            assert err == listing
        else:
            assert out == printed, f"block {i}"
    # the schema excerpt is the start of 'pixgraph schema'
    excerpt = next(t for lang, t in blocks if lang == "json")
    head = excerpt.split("    ...")[0]
    code, out, _ = _cli(["schema"])
    assert code == 0 and out.startswith(head)
