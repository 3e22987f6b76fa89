"""Bad input exits 2 with one line naming the flag, file, node or param (issue 23's
CLI cases), and ``--debug`` before or after the command prints the traceback."""
import os
import subprocess
import sys
import textwrap

import pytest

from engine_testnodes import make_registry
from pixgraph import errors
from pixgraph.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WALL = os.path.join(ROOT, "graphs", "wall_corner_shadow.yaml")


def _one_line(err: str) -> str:
    lines = err.strip("\n").split("\n")
    assert len(lines) == 1, err
    return lines[0]


def test_huge_corner_is_a_param_range_error(capsys):
    code = main(["run", WALL, "--no-disk-cache", "-q", "--set", "bg_h.corner=[1.0e+300, 1.0e+300]"])
    line = _one_line(capsys.readouterr().err)
    assert code == 2
    assert "wall_corner_shadow.yaml:" in line and "node 'bg_h'" in line and "param 'corner'" in line
    assert "above the maximum 1000000" in line


def test_junction_points_at_one_u_are_bad_input(capsys):
    own = os.path.join(ROOT, "graphs", "own_photo.yaml")
    code = main(["run", own, "--no-disk-cache", "-q", "--set", "bg_h.junction_points=[10, 300, 10, 320]"])
    line = _one_line(capsys.readouterr().err)
    assert code == 2
    assert "node 'bg_h'" in line and "param 'junction_points'" in line and "distinct u" in line


def test_negative_cache_bytes_names_the_flag(tmp_path, capsys):
    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  s: {type: t.Source}\noutputs: {o: s.out}\n")
    code = main(["run", str(g), "--no-disk-cache", "--cache-bytes", "-1"], registry=make_registry())
    assert code == 2
    line = _one_line(capsys.readouterr().err)
    assert "(--cache-bytes, PIXGRAPH_CACHE_BYTES), got -1" in line and not line.startswith("error:")


@pytest.mark.parametrize("where", ["before", "after"])
def test_debug_before_or_after_the_command_prints_the_traceback(tmp_path, capsys, where):
    g = tmp_path / "boom.yaml"
    g.write_text("pixgraph: 1\nnodes:\n  bomb: {type: t.Boom}\noutputs: {o: bomb.out}\n")
    argv = ["run", str(g), "--no-disk-cache"]
    argv = ["--debug"] + argv if where == "before" else argv + ["--debug"]
    assert main(argv, registry=make_registry()) == 1
    err = capsys.readouterr().err
    assert err.startswith("error: node 'bomb' (t.Boom): failed: ZeroDivisionError: kaboom\n")
    assert "Traceback (most recent call last)" in err and 'raise ZeroDivisionError("kaboom")' in err
    # and without it, one line
    assert main(argv[1:] if where == "before" else argv[:-1], registry=make_registry()) == 1
    assert _one_line(capsys.readouterr().err) == "error: node 'bomb' (t.Boom): failed: ZeroDivisionError: kaboom"


# Run pixgraph.cli.main in a child whose address space is capped a little above what
# it uses after importing everything, so an image of the asked size cannot be made
# (or its disk entry cannot be packed) and the MemoryError is real, not mocked.
_CHILD = textwrap.dedent("""
    import os, resource, sys
    import numpy as np
    import pixgraph.cli, pixgraph.session, pixgraph_nodes, pixgraph_nodes.constant
    from pixgraph.cli import main
    main(["run", sys.argv[1], "--no-disk-cache", "-q"])  # load everything a run loads
    with open("/proc/self/status") as f:
        vm = next(int(l.split()[1]) * 1024 for l in f if l.startswith("VmSize:"))
    headroom = int(sys.argv[3])
    resource.setrlimit(resource.RLIMIT_AS, (vm + headroom, vm + headroom))
    sys.exit(main(["run", sys.argv[2], "--disk-cache", sys.argv[4]]))
""")


def _graph(path, size):
    path.write_text(f"pixgraph: 1\nnodes:\n  c: {{type: pixgraph.Constant, params: {{width: {size}, "
                    f"height: {size}}}}}\noutputs: {{final: c.image}}\n")
    return str(path)


def _child(tmp_path, size, headroom):
    small = _graph(tmp_path / "small.yaml", 8)
    big = _graph(tmp_path / "big.yaml", size)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    return subprocess.run([sys.executable, "-c", _CHILD, small, big, str(headroom), str(tmp_path / "dc")],
                          capture_output=True, text=True, env=env, timeout=120)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc are Linux's")
def test_image_too_large_for_memory_exits_2_saying_what_to_lower(tmp_path):
    # 20000 x 20000 RGBA float32 = 6.4 GB, with 1 GB of address space to spare
    r = _child(tmp_path, 20000, 1 << 30)
    assert r.returncode == 2, r.stderr
    line = _one_line(r.stderr)
    assert line.startswith("error: node 'c' (pixgraph.Constant): ran out of memory: lower the image size")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc are Linux's")
def test_little_memory_left_for_the_disk_entry_still_finishes_the_run(tmp_path):
    # 4096^2 RGBA float32 = 256 MiB fits in 384 MiB of headroom; its disk entry is
    # written streamed (or, were it not, left out): the run ends well either way
    r = _child(tmp_path, 4096, 384 << 20)
    assert r.returncode == 0, r.stderr
    assert "final: array float32 (4096, 4096, 4)" in r.stdout


def test_every_error_class_has_its_exit_code_and_status():
    from pixgraph.events import Cancelled

    cases = [(errors.GraphError("x"), 2, 400), (errors.PathError("x"), 2, 403), (errors.UsageError("x"), 2, 400),
             (errors.InputError("x"), 2, 422), (errors.NodeInputError("n", "t.T", "x"), 2, 422),
             (errors.NodeError("n", "t.T", "x"), 1, 500), (MemoryError(), 2, 507), (Cancelled(), 130, 499),
             (RuntimeError("x"), 1, 500)]
    for exc, code, status in cases:
        assert (errors.exit_code(exc), errors.http_status(exc)) == (code, status), exc
    assert errors.message(MemoryError()).startswith("ran out of memory: lower the image size")
