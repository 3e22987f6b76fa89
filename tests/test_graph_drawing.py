"""``pixgraph graph FILE --dot/--svg``: the picture has every node, connection and
output, and its layers run left to right (every edge points right)."""
import contextlib
import io
import os
import re
import xml.etree.ElementTree as ET

from engine_testnodes import make_registry
from pixgraph.cli import main
from pixgraph.drawing import layout
from pixgraph.graph import dag, downstream, upstream
from pixgraph.session import Session

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
WALL = os.path.join(ROOT, "graphs", "wall_corner_shadow.yaml")
SVG = "{http://www.w3.org/2000/svg}"


def _run(argv, registry=None):
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(argv, registry=registry)
    return code, buf.getvalue()


def _connections(g):
    return [(ref.node, nid, port) for nid, inst in g.nodes.items() for port, ref in inst.inputs.items()]


def test_dot_lists_every_node_connection_and_output():
    g = Session().graph(WALL)
    code, text = _run(["graph", WALL, "--dot"])
    assert code == 0 and text.startswith("digraph pixgraph {\n") and text.endswith("}\n")
    edges = re.findall(r'^  "([^"]+)" -> "([^"]+)" \[label="([^"]+)"\];$', text, re.M)
    expect = {(src, dst, f"{g.nodes[dst].inputs[port].output} -> {port}") for src, dst, port in _connections(g)}
    expect |= {(ref.node, f"output:{name}", ref.output) for name, ref in g.outputs.items()}
    assert set(edges) == expect and len(edges) == len(expect) == 14
    assert '"light" [label="light\\npixgraph.Light\\nazimuth = -25' in text


def test_svg_is_a_picture_of_the_graph(tmp_path):
    out = tmp_path / "wall.svg"
    code, _ = _run(["graph", WALL, "--svg", "-o", str(out), "-q"])
    assert code == 0
    root = ET.parse(out).getroot()
    g = Session().graph(WALL)
    boxes = {e.get("data-id"): e for e in root.iter(f"{SVG}g") if e.get("class") == "node"}
    assert set(boxes) == set(g.nodes)
    assert [e.get("data-id") for e in root.iter(f"{SVG}g") if e.get("class") == "graph-output"] == ["final"]
    paths = [p for p in root.iter(f"{SVG}path") if (p.get("class") or "").startswith("edge")]
    assert len(paths) == len(_connections(g)) + len(g.outputs)
    rects = {nid: b.find(f"{SVG}rect") for nid, b in boxes.items()}
    for p in paths:
        x1, y1, *_, x2, y2 = map(float, re.findall(r"-?\d+\.?\d*", p.get("d")))
        src = p.get("data-edge").split(".")[0]
        assert x1 == float(rects[src].get("x")) + float(rects[src].get("width"))  # leaves its source's right side
        assert x2 > x1, p.get("data-edge")  # and points right, into a later layer
    # each box shows what the graph sets
    texts = "".join(t.text or "" for t in boxes["shadow"].iter(f"{SVG}text"))
    assert "pixgraph.SoftShadow" in texts and "samples = 48" in texts and "thickness = 6" in texts


def _sum_graph(s, *, with_d):
    """Sources a, b feeding Add c (a.out -> c.a, b.out -> c.b); with_d adds Add d reading
    c and a (c.out -> d.a, a.out -> d.b). The output is the last Add."""
    b = s.builder()
    b.add("t.Source", "a")
    b.add("t.Source", "b")
    b.add("t.Add", "c")
    if with_d:
        b.add("t.Add", "d")
    b.connect("a.out", "c.a")
    b.connect("b.out", "c.b")
    if with_d:
        b.connect("c.out", "d.a")
        b.connect("a.out", "d.b")
    b.output("o", "d.out" if with_d else "c.out")
    return b.build()


def test_layers_follow_the_dependencies():
    g = _sum_graph(Session(registry=make_registry()), with_d=True)
    pos = layout(g)
    assert pos == {"a": (0, 0), "b": (0, 1), "c": (1, 0), "d": (2, 0)}
    assert sorted(dag(g).edges) == [("a", "c"), ("a", "d"), ("b", "c"), ("c", "d")]
    assert upstream(g, ["c"]) == ["a", "b", "c"] and upstream(g, ["d"], stop={"c"}) == ["a", "c", "d"]
    assert downstream(g, ["b"]) == {"c", "d"} and downstream(g, ["d"]) == set()


def test_bad_graph_is_exit_2(tmp_path, capsys):
    bad = os.path.join(ROOT, "tests", "fixtures", "bad", "cycle.yaml")
    assert main(["graph", bad, "--svg"], registry=make_registry()) == 2
    assert capsys.readouterr().err.strip().endswith("node 'a': cycle: a <- b <- a")


def test_tutorial_transcript(tmp_path, monkeypatch):
    """docs/tutorial.md's 'pixgraph graph' line prints what the page shows."""
    text = open(os.path.join(ROOT, "docs", "tutorial.md")).read()
    block = re.search(r"```\n(\$ pixgraph graph .*?)```", text, re.S).group(1)
    line, printed = block.split("\n", 1)
    monkeypatch.chdir(ROOT)
    argv = line[len("$ pixgraph "):].split()
    argv[argv.index("-o") + 1] = str(tmp_path / "wall.svg")
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert main(argv) == 0
    assert err.getvalue() == printed.replace("wall.svg", str(tmp_path / "wall.svg"))
    assert (tmp_path / "wall.svg").read_text().startswith("<svg ")


def test_cycles_found_whatever_the_file_order():
    """Validation skips the networkx walk when every input comes from a node earlier in
    the file (no cycle is possible then); a node that reads a later one still builds,
    and a cycle closed by one backward edge at the end of a long chain is still found."""
    import pytest

    from pixgraph.graph import GraphBuilder, GraphError

    reg = make_registry()
    b = GraphBuilder(reg)
    b.add("t.Add", "user")           # reads 'late', defined after it: acyclic
    b.add("t.Source", "late")
    b.connect("late.out", "user.a")
    b.output("o", "user.out")
    assert upstream(b.build(), ["user"]) == ["late", "user"]

    b = GraphBuilder(reg)
    n = 300
    for i in range(n):
        b.add("t.Add", f"n{i}")
        if i:
            b.connect(f"n{i - 1}.out", f"n{i}.a")
    b.connect(f"n{n - 1}.out", "n0.a")  # closes the chain into a ring
    b.output("o", f"n{n - 1}.out")
    with pytest.raises(GraphError, match=r"cycle: n0 <- n299 <- n298 <- n297"):
        b.build()


def test_edited_graph_keeps_the_order_only_while_the_connections_stay():
    """A graph edited in its params alone shares its parent's remembered dependency
    orders (a warm run plans without walking the graph); an edit of a connection
    does not, so the new graph's order follows its new connections."""
    from pixgraph.graph import GraphBuilder

    s = Session(registry=make_registry())
    g = _sum_graph(s, with_d=False)
    assert upstream(g, ["c"]) == ["a", "b", "c"]
    edited = s.graph(g, {"a.value": 3.0})
    assert edited.nodes["a"].params["value"] == 3.0
    assert edited.__dict__["_upstream"] is g.__dict__["_upstream"]
    assert upstream(edited, ["c"]) == ["a", "b", "c"]
    rewired = GraphBuilder.from_graph(g, s.registry)
    rewired.disconnect("c.b")
    g2 = rewired.build()
    assert "_upstream" not in g2.__dict__
    assert upstream(g2, ["c"]) == ["a", "c"]
    assert upstream(g, ["c"]) == ["a", "b", "c"]   # the parent's memo is untouched
