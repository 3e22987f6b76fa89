"""The undo history and the run records are bounded in bytes, not only in count: a
posted graph may hold thousands of nodes (8,000 Constant nodes: ~13 MB a state,
shared with no other state), so 100 undo steps or 256 run records of edits of it were
gigabytes. docs/server.md, "Undo"; ``history.graph_bytes``."""
import gc
import tracemalloc

import pytest

from pixgraph import fileio
from pixgraph.graph import Graph, NodeInstance, Ref
from pixgraph.registry import Registry
from pixgraph_serve.errors import ServeError
from pixgraph_serve.history import History, Step, graph_bytes
from pixgraph_serve.runs import Runs

MiB = 1 << 20


def big_graph(n: int, tag: int) -> Graph:
    """``n`` Constant nodes (a distinct graph per ``tag``, as an edit makes: no part shared)."""
    nodes = {f"c{i}": NodeInstance(f"c{i}", "pixgraph.Constant",
                                   {"width": 8 + tag, "height": 8, "color": [0.1, 0.2, 0.3, 1.0]})
             for i in range(n)}
    return Graph(nodes, {"final": Ref("c0", "image")})


def held_by(make) -> tuple:
    """``make()``'s result and the bytes it still holds after a collection (tracemalloc)."""
    gc.collect()
    tracemalloc.start()
    try:
        out = make()
        gc.collect()
        return out, tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()


def test_the_estimate_is_not_below_what_a_loaded_graph_holds():
    reg = Registry.discover()
    text = "pixgraph: 1\nnodes:\n" + "".join(
        f"  c{i}: {{type: pixgraph.Constant, params: {{width: 8, height: 8, color: [0.1, 0.2, 0.3, 1]}}}}\n"
        for i in range(1000)) + "outputs: {final: c0.image}\n"
    fileio.loads(text, reg)                          # warm: the loader's own caches are no graph's
    graph, held = held_by(lambda: fileio.loads(text, reg))
    assert len(graph.lines) > 3000                   # its source lines are held too
    assert held <= graph_bytes(graph) <= 3 * held, (held, graph_bytes(graph))
    built, held = held_by(lambda: big_graph(1000, 0))
    assert held <= graph_bytes(built) <= 3 * held, (held, graph_bytes(built))


def test_undo_steps_of_big_graphs_are_bounded_in_bytes():
    """20 edits of an 8,000-node graph: before, all 20 states were kept (105 MiB with
    the current graph, 25 MiB now: benchmarks/serve_bytes_bench.py);
    now what fits in 64 MiB, the newest ones."""
    def edits():
        h = History(100)
        graphs = [big_graph(8000, 0)]
        for k in range(1, 21):
            graphs.append(big_graph(8000, k))
            h.record(Step(graphs[-2], {}), graphs[-1], None)
            graphs[-2] = None                          # the server holds the current graph only
        return h, graphs[-1]

    (h, now), held = held_by(edits)
    size = graph_bytes(now)
    assert 8 * MiB < size < 20 * MiB
    assert len(h.undo) == 64 * MiB // size < 20
    assert h.bytes() <= h.max_bytes
    assert [s.graph.nodes["c0"].params["width"] for s in h.undo] == list(range(28 - len(h.undo), 28))
    assert held < 64 * MiB + 3 * size, held / MiB      # what the steps and the current graph hold
    h.peek("undo")


def test_one_step_bigger_than_the_budget_is_kept():
    h = History(100, max_bytes=1 * MiB)
    a, b, c = big_graph(2000, 0), big_graph(2000, 1), big_graph(2000, 2)
    assert graph_bytes(a) > MiB
    h.record(Step(a, {}), b, None)
    h.record(Step(b, {}), c, None)
    assert [s.graph for s in h.undo] == [b]           # the newest: one undo still works
    assert h.peek("undo").graph is b
    h.moved("undo", Step(c, {}))
    with pytest.raises(ServeError):
        h.peek("undo")


def test_run_records_of_big_graphs_are_bounded_in_bytes():
    runs = Runs()
    ids = []
    for k in range(20):
        ids.append(runs.add(big_graph(8000, k), "final", ["final"]).id)
    size = graph_bytes(big_graph(8000, 0))
    assert runs.bytes <= runs.max_bytes and len(runs._runs) == runs.max_bytes // size
    assert runs.get(ids[-1]).graph.nodes["c0"].params["width"] == 27
    with pytest.raises(ServeError) as e:
        runs.get(ids[0])
    assert e.value.status == 404


def test_runs_of_one_graph_count_its_bytes_once():
    runs = Runs()
    g = big_graph(8000, 0)
    ids = [runs.add(g, "preview", ["final"]).id for _ in range(300)]
    assert runs.bytes == graph_bytes(g)
    assert len(runs._runs) == runs.max_runs          # the count bound, as before
    runs.get(ids[-256])
    with pytest.raises(ServeError):
        runs.get(ids[-257])
    other = big_graph(10, 1)
    for _ in range(256):
        runs.add(other, "final", ["final"])
    assert runs.bytes == graph_bytes(other) and runs._graphs.keys() == {id(other)}


def test_a_runs_bytes_are_estimated_off_the_event_loop(tmp_path, monkeypatch):
    """``Runs.add`` estimates a new graph's bytes (linear in its size: tens of
    milliseconds at thousands of nodes); POST /api/run called it on the event loop,
    which answers every other client."""
    import threading

    from starlette.testclient import TestClient

    from pixgraph_serve import runs as runs_module
    from pixgraph_serve.app import create_app
    from pixgraph_serve.state import ServeState
    from serve_helpers import copy_scene

    state = ServeState(copy_scene(str(tmp_path / "scene")), upload_dir=str(tmp_path / "up"))
    threads = []

    def estimate(graph):
        threads.append(threading.current_thread())
        return graph_bytes(graph)

    monkeypatch.setattr(runs_module, "graph_bytes", estimate)
    with TestClient(create_app(state)) as client:
        loop_thread = client.portal.call(threading.current_thread)
        for light in (10, 11):
            r = client.post("/api/run", json={"params": {"light.azimuth": light}, "mode": "preview"})
            assert r.status_code == 200, r.text
    assert len(threads) == 2 and all(t is not loop_thread for t in threads), threads
