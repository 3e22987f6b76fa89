"""CLI: exit codes, one-line errors for malformed graphs, and the commands."""
import glob
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from engine_testnodes import make_registry
from pixgraph.cli import main

FIXTURES = os.path.join(os.path.dirname(__file__), "fixtures")
BAD = sorted(glob.glob(os.path.join(FIXTURES, "bad", "*.yaml")))


def expectation(path):
    first = open(path).readline()
    m = re.match(r"# expect (\d+): (.*)", first)
    return int(m.group(1)), m.group(2).strip()


def test_there_are_enough_malformed_fixtures():
    assert len(BAD) >= 25


@pytest.mark.parametrize("path", BAD, ids=[os.path.basename(p)[:-5] for p in BAD])
def test_malformed_graph_exits_2_with_one_line(path, capsys):
    line, text = expectation(path)
    code = main(["validate", path], registry=make_registry())
    out, err = capsys.readouterr()
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"{path}:{line}: "), err
    assert text in err, err
    # run says the same thing
    assert main(["run", path, "--no-disk-cache"], registry=make_registry()) == 2
    assert capsys.readouterr().err == err


def test_no_yaml_tag_constructs_anything(capsys):
    assert not os.path.exists("/tmp/pixgraph-pwned")
    main(["run", os.path.join(FIXTURES, "bad", "python_object_tag.yaml"), "--no-disk-cache"],
         registry=make_registry())
    assert not os.path.exists("/tmp/pixgraph-pwned")


def test_debug_shows_the_traceback(capsys):
    code = main(["validate", os.path.join(FIXTURES, "bad", "cycle.yaml"), "--debug"], registry=make_registry())
    assert code == 2 and "Traceback" in capsys.readouterr().err


def test_set_overrides_are_validated_like_file_params(tmp_path, capsys):
    good = os.path.join(FIXTURES, "good", "format1.yaml")
    code = main(["run", good, "--no-disk-cache", "--set", "sum.k=-5000"], registry=make_registry())
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1
    assert err.startswith(f"{good}:") and "node 'sum': param 'k': -5000.0 is below the minimum -1000.0" in err
    assert main(["run", good, "--no-disk-cache", "--set", "sum.k"], registry=make_registry()) == 2
    assert "expected NODE.PARAM=VALUE" in capsys.readouterr().err
    assert main(["run", good, "--no-disk-cache", "--set", "sum.k=[1, "], registry=make_registry()) == 2
    assert "not valid YAML" in capsys.readouterr().err
    assert main(["run", good, "--no-disk-cache", "--set", "nope.k=1"], registry=make_registry()) == 2
    capsys.readouterr()


def test_run_writes_outputs_with_o(tmp_path, capsys):
    good = os.path.join(FIXTURES, "good", "format1.yaml")
    out = tmp_path / "final.npy"
    code = main(["run", good, "--no-disk-cache", "-q", "--set", "sum.k=0.25", "-o", f"final={out}"],
                registry=make_registry())
    assert code == 0, capsys.readouterr().err
    # the port type's write (the test pack's Image saves .npy)
    np.testing.assert_array_equal(np.load(out), np.full((3, 3), 4.25, np.float32))
    assert main(["run", good, "--no-disk-cache", "-o", "nope=x.png"], registry=make_registry()) == 2
    assert "no output named 'nope'" in capsys.readouterr().err
    # any node output, not only the graph's named outputs
    src = tmp_path / "src.npy"
    assert main(["run", good, "--no-disk-cache", "-q", "-o", f"src.out={src}"], registry=make_registry()) == 0
    np.testing.assert_array_equal(np.load(src), np.full((3, 3), 2.0, np.float32))
    assert main(["run", good, "--no-disk-cache", "-o", f"src.nope={src}"], registry=make_registry()) == 2
    assert "no such node output 'src.nope'" in capsys.readouterr().err


def test_node_failure_exits_1_and_names_the_node(tmp_path, capsys):
    g = tmp_path / "boom.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  bomb: {type: t.Boom}\noutputs: {o: bomb.out}\n")
    assert main(["run", str(g), "--no-disk-cache"], registry=make_registry()) == 1
    err = capsys.readouterr().err
    assert err == "error: node 'bomb' (t.Boom): failed: ZeroDivisionError: kaboom\n"
    assert main(["run", str(g), "--no-disk-cache", "--debug"], registry=make_registry()) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "kaboom" in err


def test_explain_and_cache_commands(tmp_path, capsys):
    good = os.path.join(FIXTURES, "good", "format1.yaml")
    disk = str(tmp_path / "cache")
    reg = make_registry()
    assert main(["explain", good, "--disk-cache", disk], registry=reg) == 0
    table = capsys.readouterr().out
    assert re.search(r"sum\s+t\.Add\s+run\s+\w+\s+new", table) and "src" in table
    assert main(["run", good, "--disk-cache", disk, "-q"], registry=reg) == 0
    assert main(["explain", good, "--disk-cache", disk, "--set", "sum.k=2"], registry=reg) == 0
    table = capsys.readouterr().out
    assert re.search(r"sum\s+t\.Add\s+run\s+\w+\s+params\.k changed", table)
    assert re.search(r"src\s+t\.Source\s+disk", table)  # a new session: found on disk
    assert main(["cache", "stats", "--disk-cache", disk], registry=reg) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["entries"] == 2 and stats["bytes"] > 0
    assert main(["cache", "clear", "--disk-cache", disk], registry=reg) == 0
    assert "removed 2 entries" in capsys.readouterr().out
    main(["cache", "stats", "--disk-cache", disk], registry=reg)
    assert json.loads(capsys.readouterr().out)["entries"] == 0
    assert main(["cache", "stats", "--no-disk-cache"], registry=reg) == 2
    assert "--no-disk-cache leaves no disk cache" in capsys.readouterr().err
    missing = str(tmp_path / "never-made")
    assert main(["cache", "clear", "--disk-cache", missing], registry=reg) == 0
    assert "removed 0 entries" in capsys.readouterr().out and not os.path.exists(missing)


def test_nodes_listing_reference_and_schema(capsys):
    reg = make_registry()
    assert main(["nodes"], registry=reg) == 0
    listing = capsys.readouterr().out
    assert re.search(r"^t\.Scale\s+v2\s+x \* factor", listing, re.M)
    assert main(["nodes", "t.Source"], registry=reg) == 0
    ref = capsys.readouterr().out
    assert "value: float = 1.0 - pixel value" in ref and "[-1000, 1000]" in ref
    assert "size: int = 4 [px] - side length" in ref and "a | b | c" in ref
    assert "out: Image - constant image" in ref
    assert main(["nodes", "t.Sourc"], registry=reg) == 2
    assert "did you mean 't.Source'" in capsys.readouterr().err
    assert main(["nodes", "--markdown"], registry=reg) == 0
    md = capsys.readouterr().out
    assert "## t.Source" in md and "| `factor` | float | 1.0 | [0, 100] |" in md
    assert main(["schema"], registry=reg) == 0
    assert json.loads(capsys.readouterr().out)["properties"]["pixgraph"] == {"const": 1}


def _cli(*args, **env):
    return subprocess.run([sys.executable, "-m", "pixgraph", *args], capture_output=True, text=True,
                          timeout=120, env={**os.environ, **env})


@pytest.mark.parametrize("name", ["version_too_new", "yaml_syntax", "python_object_tag"])
def test_malformed_graph_via_subprocess(name):
    # the installed registry: these errors come before any node type is looked up
    path = os.path.join(FIXTURES, "bad", f"{name}.yaml")
    line, text = expectation(path)
    p = _cli("validate", path)
    assert p.returncode == 2
    assert p.stderr == p.stderr.splitlines()[0] + "\n" and p.stderr.startswith(f"{path}:{line}: ")
    assert text in p.stderr


def test_subprocess_unknown_param_on_a_builtin_node(tmp_path):
    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  blur:\n    type: pixgraph.Constant\n    params: {colour: [1, 0, 0, 1]}\n")
    p = _cli("run", str(g), "--no-disk-cache")
    assert p.returncode == 2 and p.stderr.startswith(f"{g}:5: node 'blur': param 'colour': unknown param")
    assert p.stderr.count("\n") == 1


def test_progress_bar_only_on_a_terminal_and_not_with_quiet(monkeypatch):
    import io

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    good = os.path.join(FIXTURES, "good", "format1.yaml")
    for stream, args, bar in ((Terminal(), [], True), (Terminal(), ["-q"], False), (io.StringIO(), [], False)):
        monkeypatch.setattr(sys, "stderr", stream)
        assert main(["run", good, "--no-disk-cache", *args], registry=make_registry()) == 0
        assert ("node/s" in stream.getvalue()) == bar, stream.getvalue()


def test_explain_says_when_a_changed_node_is_served_from_cache(tmp_path):
    from pixgraph.session import Session
    good = os.path.join(FIXTURES, "good", "format1.yaml")
    s = Session(registry=make_registry(), disk_cache=None)
    s.run(good)                                   # k = 1.5
    s.run(good, params={"sum.k": 2})              # k = 2: now the last run
    table = s.explain(good)                       # back to 1.5: changed, yet cached
    assert re.search(r"sum\s+t\.Add\s+memory\s+\w+\s+params\.k changed; an earlier result is in the memory cache",
                     table), table
    assert "src" not in table                     # not needed: its consumer is cached
