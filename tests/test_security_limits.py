"""Bounded resources: small hostile graph files, oversized images and input files
are refused as bad input with one short line; hashing streams files."""
import os
import tracemalloc

import numpy as np
import pytest

from pixgraph import fileio
from pixgraph.cli import main
from pixgraph.graph import MAX_ERROR_LINE, GraphError
from pixgraph.hashing import FileHasher
from pixgraph.registry import Registry
from pixgraph_nodes.ops.imageio import write_image

HEAD = "pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 4, height: 4}}\noutputs: {o: c.image}\n"
BOMB = "".join([HEAD, "x: &a0 [l,l,l,l,l,l,l,l,l,l]\n"] +
               [f"x{i}: &a{i} [" + ",".join([f"*a{i-1}"] * 10) + "]\n" for i in range(1, 9)])


@pytest.mark.parametrize("text, message", [
    (BOMB, "more than 200000 values once aliases are expanded"),
    (HEAD + "deep: " + "[" * 100 + "]" * 100 + "\n", "nested deeper than 32 levels"),
    (HEAD + "deep: " + "{a: " * 40 + "1" + "}" * 40 + "\n", "nested deeper than 32 levels"),
    (HEAD + "rec: &r [1, *r]\n", "an alias refers to a node that contains it"),
    (HEAD.replace("width: 4", "width: '" + "9" * 20_000 + "'"), "a value of 20000 characters"),
], ids=["alias_bomb", "deep_lists", "deep_maps", "recursive_alias", "long_string"])
def test_hostile_yaml_is_refused_before_it_is_built(text, message, tmp_path, capsys):
    with pytest.raises(GraphError, match=message):
        fileio.loads(text, Registry.discover())
    g = tmp_path / "g.yaml"
    g.write_text(text)
    assert main(["validate", str(g)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0] and len(err[0]) <= MAX_ERROR_LINE


def test_graph_file_size_limit(tmp_path, capsys):
    g = tmp_path / "g.yaml"
    g.write_text(HEAD + "# " + "x" * fileio.MAX_FILE_BYTES + "\n")
    assert main(["validate", str(g)]) == 2
    assert "larger than 4194304 bytes" in capsys.readouterr().err


def test_error_lines_are_cut(tmp_path, capsys):
    g = tmp_path / "g.yaml"
    g.write_text(HEAD.replace("pixgraph.Constant", "Q" * 5000))  # quoted back in "unknown node type"
    assert main(["validate", str(g)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and len(err[0]) == MAX_ERROR_LINE and err[0].endswith("...")
    assert "node 'c'" in err[0]


def test_image_size_is_checked_from_the_header(tmp_path, capsys, monkeypatch):
    write_image(tmp_path / "big.png", np.zeros((40, 50, 4), np.float32))
    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  load: {type: pixgraph.LoadImage, params: {path: big.png}}\n"
                 "outputs: {o: load.image}\n")
    assert main(["run", str(g), "-q", "--no-disk-cache"]) == 0
    capsys.readouterr()
    monkeypatch.setenv("PIXGRAPH_MAX_PIXELS", "1999")  # 40 x 50 = 2000
    assert main(["run", str(g), "-q", "--no-disk-cache"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "node 'load'" in err[0] and "50x40" in err[0] and "PIXGRAPH_MAX_PIXELS" in err[0]
    # a file that is not an image at all is bad input too, not an internal failure
    (tmp_path / "big.png").write_bytes(b"\x89PNG\r\n\x1a\n" + b"\0" * 100)
    monkeypatch.delenv("PIXGRAPH_MAX_PIXELS")
    assert main(["run", str(g), "-q", "--no-disk-cache"]) == 2


def test_input_file_size_limit(tmp_path, capsys, monkeypatch):
    write_image(tmp_path / "a.png", np.zeros((4, 4, 4), np.float32))
    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  load: {type: pixgraph.LoadImage, params: {path: a.png}}\n"
                 "outputs: {o: load.image}\n")
    monkeypatch.setenv("PIXGRAPH_MAX_FILE_BYTES", "10")
    assert main(["run", str(g), "-q", "--no-disk-cache"]) == 2
    assert "PIXGRAPH_MAX_FILE_BYTES" in capsys.readouterr().err


def test_hashing_streams_the_file(tmp_path):
    p = tmp_path / "big.bin"
    with open(p, "wb") as f:
        f.truncate(128 << 20)  # 128 MiB (sparse)
    tracemalloc.start()
    digest = FileHasher()(str(p))
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    import hashlib

    h = hashlib.sha256()
    zeros = bytes(1 << 20)
    for _ in range(128):
        h.update(zeros)
    assert digest == h.hexdigest()
    assert peak < 8 << 20, peak  # 1 MiB chunks, never the whole file
    os.remove(p)
