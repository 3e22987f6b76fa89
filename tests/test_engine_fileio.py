"""Graph files: canonical dump, round trips, migration, schema, errors with lines; the Graph value."""
import dataclasses
import os

import jsonschema
import pytest

from engine_testnodes import make_registry
from pixgraph import fileio
from pixgraph.graph import Graph, GraphBuilder, GraphError, Ref

FIXTURES = os.path.join(os.path.dirname(__file__), "fixtures")


@pytest.fixture
def reg():
    return make_registry()


def test_format0_is_migrated_to_the_same_graph_as_format1(reg):
    old = fileio.load(os.path.join(FIXTURES, "good", "format0.yaml"), reg)
    new = fileio.load(os.path.join(FIXTURES, "good", "format1.yaml"), reg)
    assert old == new
    assert old.nodes["sum"].inputs["a"] == Ref("src", "out")
    assert dict(old.nodes["src"].params) == {"value": 2.0, "size": 3}
    text = open(os.path.join(FIXTURES, "good", "format1.yaml")).read()
    body = "".join(line for line in text.splitlines(True) if not line.startswith("#"))
    assert fileio.dumps(old) == body  # migrated and written canonically


def test_load_dump_load_gives_same_graph_and_same_text(reg, tmp_path):
    messy = """
outputs: {z: b.out, a: src.out}
nodes:
  src: {params: {value: 3, size: 2}, type: t.Source}
  b: {inputs: {b: src.out, a: src.out}, type: t.Add, params: {k: -1}}
pixgraph: 1
"""
    g1 = fileio.loads(messy, reg)
    t1 = fileio.dumps(g1)
    g2 = fileio.loads(t1, reg)
    assert g2 == g1 and fileio.dumps(g2) == t1
    assert t1.index("  src:") < t1.index("  b:")  # nodes in the file's order
    assert "value: 3.0" in t1  # params coerced to canonical floats
    p = tmp_path / "g.yaml"
    fileio.dump(g1, p)
    assert fileio.load(p, reg) == g1 and p.read_text() == t1


def test_builder_graph_round_trips_and_is_immutable(reg):
    b = GraphBuilder(reg)
    b.add("t.Source", "src", value=1)
    b.add("t.Scale", "sc", factor=2)
    b.connect("src.out", "sc.x")
    b.set("sc", factor=4)
    b.output("final", "sc.out")
    g = b.build()
    assert g.nodes["sc"].params["factor"] == 4.0
    with pytest.raises(TypeError):
        g.nodes["sc"].params["factor"] = 5.0
    with pytest.raises(TypeError):
        g.nodes["x"] = None
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.file = "x"
    assert fileio.loads(fileio.dumps(g), reg) == g
    # editing through a builder leaves the original untouched
    b2 = GraphBuilder.from_graph(g, reg)
    b2.unset("sc", "factor")
    g2 = b2.build()
    assert "factor" not in g2.nodes["sc"].params and g.nodes["sc"].params["factor"] == 4.0
    assert g2 != g


def test_builder_errors_name_node_and_field(reg):
    b = GraphBuilder(reg)
    b.add("t.Source", "src")
    with pytest.raises(GraphError, match="already exists"):
        b.add("t.Source", "src")
    b.add("t.Scale", "sc", factor=1000)
    b.connect("src.out", "sc.x")
    with pytest.raises(GraphError) as ei:
        b.build()
    e = ei.value
    assert (e.node, e.field, e.file, e.line) == ("sc", "params.factor", None, None)
    assert str(e) == "node 'sc': param 'factor': 1000.0 is above the maximum 100.0"
    with pytest.raises(GraphError, match="expected 'node.output'"):
        b.connect("src", "sc.x")
    with pytest.raises(GraphError, match="no such node"):
        b.set("nope", k=1)


def test_error_attributes_from_a_file(reg):
    path = os.path.join(FIXTURES, "bad", "out_of_range.yaml")
    with pytest.raises(GraphError) as ei:
        fileio.load(path, reg)
    e = ei.value
    assert (e.file, e.line, e.node, e.field) == (path, 8, "sc", "params.factor")
    assert str(e) == f"{path}:8: node 'sc': param 'factor': -1.0 is below the minimum 0.0"


def test_schema_accepts_good_files_and_rejects_bad_ones(reg):
    import yaml

    schema = fileio.json_schema(reg)
    jsonschema.Draft202012Validator.check_schema(schema)
    doc = fileio.to_document(fileio.load(os.path.join(FIXTURES, "good", "format1.yaml"), reg))
    jsonschema.validate(doc, schema)
    for bad in ("unknown_param", "out_of_range", "bad_choice", "missing_type", "version_too_new"):
        with open(os.path.join(FIXTURES, "bad", f"{bad}.yaml")) as f:
            with pytest.raises(jsonschema.ValidationError):
                jsonschema.validate(yaml.safe_load(f), schema)
    assert fileio.schema_text(reg) == fileio.schema_text(reg)  # deterministic


def test_path_params_are_relative_to_the_graph_file(reg, tmp_path):
    sub = tmp_path / "g"
    sub.mkdir()
    (sub / "data.bin").write_bytes(b"12345")
    (sub / "graph.yaml").write_text("pixgraph: 1\nnodes:\n  f: {type: t.FileLen, params: {path: data.bin}}\n"
                                    "outputs: {n: f.out}\n")
    from pixgraph.session import Session

    cwd = os.getcwd()
    os.chdir(tmp_path)  # not the graph's folder
    try:
        out = Session(registry=reg).run(str(sub / "graph.yaml"))
    finally:
        os.chdir(cwd)
    assert out["n"][0, 0] == 5
    g = fileio.load(sub / "graph.yaml", reg)
    assert g.base_dir == str(sub) and g.resolve_path("data.bin") == str(sub / "data.bin")
    assert fileio.dumps(g).count("data.bin") == 1  # saved relative, as written


def test_graph_value_equality_ignores_location(reg):
    a = fileio.loads("pixgraph: 1\nnodes: {s: {type: t.Source}}\n", reg, file="a.yaml")
    b = fileio.loads("pixgraph: 1\nnodes:\n\n\n  s: {type: t.Source}\n", reg, file="b.yaml")
    assert a == b and a.lines != b.lines
    assert isinstance(a, Graph)


def test_random_graphs_round_trip_through_text(reg):
    import random

    from pixgraph.session import Session
    from test_engine_cache_equivalence import random_edit, random_graph

    rng = random.Random(5)
    s = Session(registry=reg)
    for _ in range(100):
        g = random_graph(rng, s)
        g = s.graph(g, random_edit(rng, g))
        text = fileio.dumps(g)
        back = fileio.loads(text, reg)
        assert back == g and fileio.dumps(back) == text


def test_dump_with_registry_rebases_relative_paths(tmp_path):
    """A graph saved into another folder still finds its files."""
    import pathlib
    from pixgraph.registry import Registry
    reg = Registry.discover()
    src = pathlib.Path(__file__).resolve().parents[1] / "graphs" / "wall_corner_shadow.yaml"
    g = fileio.load(src, reg)
    out = tmp_path / "elsewhere" / "g.yaml"
    out.parent.mkdir()
    fileio.dump(g, out, registry=reg)
    g2 = fileio.load(out, reg)
    p1 = g.base_dir + "/" + g.nodes["cutout"].params["path"]
    p2 = g2.base_dir + "/" + g2.nodes["cutout"].params["path"]
    assert pathlib.Path(p1).resolve() == pathlib.Path(p2).resolve()
    # without the registry, paths are written as given
    fileio.dump(g, tmp_path / "asis.yaml")
    assert "path: assets/figure.png" in (tmp_path / "asis.yaml").read_text()
