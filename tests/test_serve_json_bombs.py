"""JSON bodies an attacker sends with the token (docs/server.md, "Errors"): NaN,
Infinity, 1e400 and 4,300-digit integers are refused by the param checks, deep
nesting by the depth check; a large body (a JSON edit is a few kilobytes) is refused
over ``Limits.max_json_bytes`` (1 MiB) before it is parsed, and every body is parsed
on a worker thread, not on the event loop that answers every other client. Before,
24 MB of a 2-million-point list was parsed and walked on the event loop: the page's
requests waited 8.6-17 s (benchmarks/serve_bounds_bench.py, two runs; 256 MB, the body limit,
about ten times that). And numbers in
a query or header: '²' is a digit to ``str.isdigit`` but not to ``int()`` (500 before)."""
import json
import threading

import httpx
import pytest

from pixgraph_serve import app as app_module
from serve_helpers import copy_scene, running_server

JSON = {"Content-Type": "application/json"}


@pytest.fixture(scope="module")
def url(tmp_path_factory):
    graph = copy_scene(str(tmp_path_factory.mktemp("bombs") / "scene"))
    with running_server(graph) as (url, _):
        yield url


@pytest.mark.parametrize("body, field", [
    ('{"params": {"light.elevation": NaN}}', "params.elevation"),
    ('{"params": {"light.radius": Infinity}}', "params.radius"),
    ('{"params": {"light.azimuth": 1e400}}', "params.azimuth"),
    ('{"params": {"light.azimuth": -Infinity}}', "params.azimuth"),
    ('{"light_tip": [NaN, 1]}', "light_tip"),
    ('{"light_elevation": NaN}', "light_elevation"),
    ('{"light_tip": [' + "9" * 400 + ', 1]}', "light_tip"),            # beyond a float: a 500 before
    ('{"light_elevation": ' + "9" * 4000 + "}", "light_elevation"),
])
def test_non_finite_numbers_are_refused(url, body, field):
    r = httpx.post(url + "/api/params", content=body, headers=JSON, timeout=60)
    assert r.status_code == 400 and r.json().get("field") == field, r.text


def test_huge_integers_and_deep_nesting_are_400(url):
    r = httpx.post(url + "/api/params", content='{"params": {"light.azimuth": ' + "9" * 5000 + "}}",
                   headers=JSON, timeout=60)
    assert r.status_code == 400 and "not valid JSON" in r.json()["error"]
    r = httpx.post(url + "/api/params", content="[" * 100_000 + "]" * 100_000, headers=JSON, timeout=60)
    assert r.status_code == 400 and "nested" in r.json()["error"]


def test_a_large_json_body_is_refused_before_parsing(url):
    body = json.dumps({"params": {"bg_h.junction_points": [[0.1, 0.2]] * 200_000}})
    assert len(body) > 1 << 20
    r = httpx.post(url + "/api/params", content=body, headers=JSON, timeout=60)
    assert r.status_code == 413 and "JSON" in r.json()["error"], r.text
    # the same without Content-Length (chunked): counted while it arrives
    r = httpx.post(url + "/api/params", content=iter([body[i:i + 65536].encode() for i in range(0, len(body), 65536)]),
                   headers=JSON, timeout=60)
    assert r.status_code == 413
    # an edit still works
    r = httpx.post(url + "/api/params", json={"params": {"light.azimuth": 12}}, timeout=60)
    assert r.status_code == 200, r.text


def test_json_is_parsed_off_the_event_loop(tmp_path, monkeypatch):
    from starlette.testclient import TestClient

    from pixgraph_serve.app import create_app
    from pixgraph_serve.state import ServeState

    state = ServeState(copy_scene(str(tmp_path / "scene")), upload_dir=str(tmp_path / "up"))
    threads = []
    real = app_module.json.loads

    def loads(raw, *a, **k):
        threads.append(threading.current_thread())
        return real(raw, *a, **k)

    monkeypatch.setattr(app_module.json, "loads", loads)
    with TestClient(create_app(state)) as client:
        loop_thread = client.portal.call(threading.current_thread)
        r = client.post("/api/params", json={"params": {"light.azimuth": 13}})
        assert r.status_code == 200, r.text
    assert threads and all(t is not loop_thread for t in threads), threads


@pytest.mark.parametrize("scale", ["\u00b2", "\u00b9", "\u2460"])       # '²', '¹', '①': isdigit, int() refuses
def test_a_unicode_digit_scale_is_400_not_500(url, scale):
    r = httpx.get(url + "/api/outputs/final.png", params={"scale": scale}, timeout=120)
    assert r.status_code == 400 and r.json()["field"] == "scale", r.text


def test_a_unicode_digit_port_in_host_is_refused():
    from pixgraph_serve.guard import Guard

    guard = Guard(None, port=8765, token=None)
    assert not guard.host_ok("127.0.0.1:\u00b2")
    assert guard.host_ok("127.0.0.1:8765")


BIG = "9" * 5000          # over Python's limit of 4300 digits for int(): a ValueError, not a YAMLError


def test_a_posted_graph_with_a_5000_digit_integer_is_400(url):
    graph = httpx.get(url + "/api/graph.yaml", timeout=60).text
    text = graph.replace("azimuth:", f"azimuth: {BIG}\n      _was:", 1)
    assert text != graph
    r = httpx.post(url + "/api/graph", content=text, headers={"Content-Type": "application/yaml"}, timeout=60)
    assert r.status_code == 400 and "4300 digits" in r.json()["error"] and r.json().get("line"), r.text


def test_5000_digit_integers_are_bad_input_in_files_manifests_and_sets(tmp_path, capsys):
    from pixgraph import fileio
    from pixgraph.cli import main
    from pixgraph.errors import GraphError
    from pixgraph.registry import Registry

    text = f"pixgraph: 1\nnodes:\n  c: {{type: pixgraph.Constant, params: {{width: {BIG}}}}}\noutputs: {{}}\n"
    with pytest.raises(GraphError) as e:
        fileio.loads(text, Registry.discover())
    assert e.value.line == 3 and "4300 digits" in e.value.message
    graph = tmp_path / "g.yaml"
    graph.write_text("pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 8, height: 8}}\n"
                     "outputs: {final: c.image}\n")
    (tmp_path / "rows.csv").write_text(f"id,c.width\nr1,{BIG}\n")
    for args in (["batch", str(graph), str(tmp_path / "rows.csv"), "--no-disk-cache", "-o", f"final={tmp_path}/o/{{row}}.png"],
                 ["run", str(graph), "--set", f"c.width={BIG}", "-o", f"final={tmp_path}/x.png"]):
        capsys.readouterr()
        assert main(args) == 2, args[0]
        err = capsys.readouterr().err.strip()
        assert "\n" not in err and "4300 digits" in err, err


HEX = "0x" + "f" * 5000   # 20,000 bits: YAML reads a hex (or sexagesimal) int whatever its size


@pytest.mark.parametrize("value", [HEX, "1" + ":0" * 3000, "9" * 400])
def test_integers_beyond_a_floats_range_are_bad_input_at_their_line(value):
    """``int()``'s 4300-digit limit is for decimal text only: a hex or sexagesimal
    integer of any size was read, and ``float()`` (OverflowError) or ``str()``
    (ValueError) of it later stopped ``pixgraph run`` with exit 1 and made the
    server's POST /api/graph a 500."""
    from pixgraph import fileio
    from pixgraph.errors import GraphError
    from pixgraph.registry import Registry

    for text in (f"pixgraph: 1\nnodes:\n  c: {{type: pixgraph.Constant, params: {{width: {value}}}}}\noutputs: {{}}\n",
                 f"pixgraph: {value}\nnodes: {{}}\noutputs: {{}}\n"):
        with pytest.raises(GraphError) as e:
            fileio.loads(text, Registry.discover())
        assert "beyond a float's range" in e.value.message and e.value.line == text[:text.index(value)].count("\n") + 1


def test_a_posted_graph_with_a_hex_integer_is_400(url):
    graph = httpx.get(url + "/api/graph.yaml", timeout=60).text
    text = graph.replace("azimuth:", f"azimuth: {HEX}\n      _was:", 1)
    r = httpx.post(url + "/api/graph", content=text, headers={"Content-Type": "application/yaml"}, timeout=60)
    assert r.status_code == 400 and "float's range" in r.json()["error"] and r.json().get("line"), r.text


def test_integers_beyond_a_floats_range_are_param_errors_in_sets_manifests_and_edits(tmp_path, capsys, url):
    """Where no graph file's loader reads them (a --set value, a manifest cell, a JSON
    edit), the param's check refuses them: exit 2, a failed row naming the param (as
    1e400 is), 400; not exit 1 with 'Exceeds the limit (4300 digits)', nor a 500."""
    from pixgraph.cli import main

    graph = tmp_path / "g.yaml"
    graph.write_text("pixgraph: 1\nnodes:\n  c: {type: pixgraph.Constant, params: {width: 8, height: 8}}\n"
                     "outputs: {final: c.image}\n")
    (tmp_path / "rows.csv").write_text(f"id,c.color\nr1,\"[{'9' * 400}, 0, 0, 1]\"\n")
    for args in (["run", str(graph), "--set", f"c.width={HEX}", "-o", f"final={tmp_path}/x.png"],
                 ["run", str(graph), "--set", f"c.color=[{HEX}, 0, 0, 1]", "-o", f"final={tmp_path}/x.png"],
                 ["batch", str(graph), str(tmp_path / "rows.csv"), "--no-disk-cache", "-o", f"final={tmp_path}/o/{{row}}.png"]):
        capsys.readouterr()
        assert main(args) == (1 if args[0] == "batch" else 2), args[:3]
        out = capsys.readouterr()
        said = out.out if args[0] == "batch" else out.err
        assert "param 'color'" in said or args[3].startswith("c.width"), said[:1000]
        assert "beyond a float's range" in said and len(said) < 1000, said[:1000]
    for body in ('{"params": {"bg_h.junction_points": [[' + "9" * 400 + ", 1]]}}",
                 '{"params": {"light.azimuth": ' + "9" * 4000 + "}}"):
        r = httpx.post(url + "/api/params", content=body, headers=JSON, timeout=60)
        assert r.status_code == 400 and "beyond a float's range" in r.json()["error"], r.text[:500]
