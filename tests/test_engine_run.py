"""Engine: lazy pull evaluation, cache keys and plans, events, cancellation, errors."""
import threading

import numpy as np
import pytest

from engine_testnodes import make_registry
from pixgraph import events as E
from pixgraph.engine import NodeError
from pixgraph.graph import GraphError
from pixgraph.session import Session


@pytest.fixture
def calls():
    return []


@pytest.fixture
def session(calls):
    return Session(registry=make_registry(calls), cache_bytes=1 << 26)


def diamond(session):
    """src -> a -> s1 ; src -> b ; (a, b) -> top ; plus an unrelated branch."""
    b = session.builder()
    b.add("t.Source", "src", value=2.0)
    b.add("t.Add", "a", k=1.0)
    b.add("t.Scale", "s1", factor=3.0)
    b.add("t.Add", "b2", k=10.0)
    b.add("t.Add", "top")
    b.add("t.Source", "other", value=7.0)
    b.add("t.Add", "other2")
    b.connect("src.out", "a.a")
    b.connect("a.out", "s1.x")
    b.connect("src.out", "b2.a")
    b.connect("s1.out", "top.a")
    b.connect("b2.out", "top.b")
    b.connect("other.out", "other2.a")
    b.output("final", "top.out")
    b.output("side", "other2.out")
    b.output("mean", "s1.mean")
    return b.build()


def test_only_ancestors_of_requested_outputs_run(session, calls):
    g = diamond(session)
    out = session.run(g, outputs=["final"])
    assert sorted(calls) == ["a", "b2", "s1", "src", "top"]
    # (2 + 1) * 3 + (2 + 10) = 21
    assert out["final"][0, 0] == 21.0
    calls.clear()
    out = session.run(g, outputs=["mean"])  # already computed: nothing runs
    assert calls == [] and out["mean"] == 9.0
    out = session.run(g, outputs=["side"])
    assert calls == ["other", "other2"]


def test_param_change_reruns_only_downstream(session, calls):
    g = diamond(session)
    session.run(g)
    calls.clear()
    out = session.run(g, params={"a.k": 2.0})
    assert sorted(calls) == ["a", "s1", "top"]  # src, b2 and the other branch are cached
    assert out["final"][0, 0] == (2 + 2) * 3 + 12
    calls.clear()
    session.run(g, params={"a": {"k": 2.0}})  # same values, other spelling: all cached
    assert calls == []


def test_non_cache_param_does_not_rerun(session, calls):
    g = diamond(session)
    session.run(g)
    calls.clear()
    session.run(g, params={"src.chatty": True})
    assert calls == []


def test_plan_says_what_runs_and_why(session, calls):
    g = diamond(session)
    plan = session.plan(g, outputs=["final"])
    assert {s.node_id: s.status for s in plan.steps} == dict.fromkeys(["src", "a", "s1", "b2", "top"], "run")
    assert all(s.reason == "new" for s in plan.steps)
    assert calls == []  # planning computes nothing
    session.run(g, outputs=["final"])
    plan = session.plan(g, outputs=["final"], params={"a.k": 5.0})
    st = {s.node_id: (s.status, s.reason) for s in plan.steps}
    assert st["a"] == ("run", "params.k changed")
    assert st["s1"] == ("run", "input x changed")
    assert st["top"] == ("run", "input a changed")
    assert st["src"] == ("memory", "unchanged") and st["b2"] == ("memory", "unchanged")
    # a cached node's inputs are not needed at all
    plan = session.plan(g, outputs=["final"])
    assert [(s.node_id, s.status) for s in plan.steps] == [("top", "memory")]
    assert "top" in plan.table() and "memory" in plan.table()


def test_keys_are_shared_by_identical_nodes_and_change_with_parts(session, calls):
    b = session.builder()
    b.add("t.Source", "x", value=1.0)
    b.add("t.Source", "y", value=1.0)
    b.add("t.Source", "z", value=1.5)
    for n in "xyz":
        b.output(n, f"{n}.out")
    plan = session.plan(b.build())
    assert plan.keys["x"] == plan.keys["y"] != plan.keys["z"]
    session.run(b.build())
    assert len(calls) == 2  # y is served by x's entry


def test_impl_version_and_file_content_in_reason(session, calls, tmp_path):
    f = tmp_path / "data.bin"
    f.write_bytes(b"abc")
    b = session.builder(base_dir=str(tmp_path))
    b.add("t.FileLen", "fl", path="data.bin")
    b.output("n", "fl.out")
    g = b.build()
    assert session.run(g)["n"][0, 0] == 3
    assert session.plan(g).steps[0].status == "memory"
    f.write_bytes(b"abcdef")
    step = session.plan(g).steps[0]
    assert (step.status, step.reason) == ("run", "file content changed (params.path)")
    assert session.run(g)["n"][0, 0] == 6


def test_memory_cache_is_bounded_in_bytes(calls):
    # each Source(size=64) entry is 64*64*4 = 16 KiB of array + 64 bytes of dict; room for two
    s = Session(registry=make_registry(calls), cache_bytes=2 * (16384 + 64) + 100)
    b = s.builder()
    for i in range(4):
        b.add("t.Source", f"s{i}", value=float(i), size=64)
        b.output(f"o{i}", f"s{i}.out")
    g = b.build()
    s.run(g)
    assert s.memory.bytes <= s.memory.limit_bytes and len(s.memory) == 2
    calls.clear()
    s.run(g, outputs=["o3"])  # most recent: still cached
    assert calls == []
    s.run(g, outputs=["o0"])  # evicted: runs again
    assert calls == ["s0"]


def test_cache_bytes_from_environment(monkeypatch, calls):
    monkeypatch.setenv("PIXGRAPH_CACHE_BYTES", "12345")
    assert Session(registry=make_registry(calls)).memory.limit_bytes == 12345
    assert Session(registry=make_registry(calls), cache_bytes=99).memory.limit_bytes == 99


def test_bind_host_array(session, calls):
    g = diamond(session)
    host = np.full((4, 4), 5.0, np.float32)
    out = session.run(g, outputs=["final"], bind={"src": host})
    assert "src" not in calls
    assert out["final"][0, 0] == (5 + 1) * 3 + 15
    calls.clear()
    session.run(g, outputs=["final"], bind={"src": host.copy()})  # same bytes: same key
    assert calls == []
    host2 = host.copy()
    host2[0, 0] = 6.0
    out = session.run(g, outputs=["final"], bind={"src": host2})
    assert sorted(calls) == ["a", "b2", "s1", "top"]
    with pytest.raises(GraphError, match="bound value"):
        session.run(g, bind={"src": [1, 2]})
    with pytest.raises(GraphError, match="cannot bind"):
        session.run(g, bind={"nope": host})


def test_events_progress_and_timings(session, calls):
    b = session.builder()
    b.add("t.Source", "s")
    b.add("t.Slow", "slow", steps=4)
    b.connect("s.out", "slow.x")
    b.output("o", "slow.out")
    g = b.build()
    seen = []
    session.run(g, on_event=seen.append)
    kinds = [type(e).__name__ for e in seen]
    assert kinds[0] == "RunStarted" and kinds[-1] == "RunFinished"
    prog = [e for e in seen if isinstance(e, E.NodeProgress)]
    assert [p.fraction for p in prog] == [0.25, 0.5, 0.75, 1.0] and prog[0].message == "step 1"
    slow = [type(e).__name__ for e in seen if getattr(e, "node_id", None) == "slow"]
    assert slow == ["NodeStarted"] + ["NodeProgress"] * 4 + ["NodeFinished"]
    assert set(session.last_run.timings) == {"s", "slow"}
    assert all(t >= 0 for t in session.last_run.timings.values())
    seen.clear()
    session.run(g, on_event=seen.append)
    assert [e for e in seen if isinstance(e, E.NodeCached)] == [E.NodeCached("slow", "memory")]


def test_cancellation(session, calls):
    b = session.builder()
    b.add("t.Source", "s")
    b.add("t.Slow", "slow", steps=200, delay=0.01)
    b.connect("s.out", "slow.x")
    b.output("o", "slow.out")
    token = E.CancelToken()

    def on_event(ev):
        if isinstance(ev, E.NodeProgress) and ev.fraction >= 0.05:
            token.cancel()

    with pytest.raises(E.Cancelled):
        session.run(b.build(), cancel=token, on_event=on_event)
    assert session.plan(b.build()).step("slow").status == "run"  # nothing half-cached
    # cancelling from another thread before the run starts stops it between nodes
    t2 = E.CancelToken()
    canceller = threading.Thread(target=t2.cancel)
    canceller.start()
    canceller.join(30)  # cancelled before the run starts, however slow the machine
    with pytest.raises(E.Cancelled):
        session.run(b.build(), cancel=t2)


def test_wrong_output_type_and_node_exception_name_the_node(session, calls):
    b = session.builder()
    b.add("t.WrongType", "liar")
    b.add("t.Boom", "bomb")
    b.output("l", "liar.out")
    b.output("b", "bomb.out")
    g = b.build()
    with pytest.raises(NodeError, match=r"node 'liar' \(t.WrongType\): output 'out' is not a valid Image"):
        session.run(g, outputs=["l"])
    with pytest.raises(NodeError, match=r"node 'bomb' \(t.Boom\): failed: ZeroDivisionError: kaboom") as ei:
        session.run(g, outputs=["b"])
    assert isinstance(ei.value.__cause__, ZeroDivisionError)


def test_sink_runs_every_time_it_is_requested_and_only_then(session, calls, tmp_path):
    b = session.builder(base_dir=str(tmp_path))
    b.add("t.Source", "s", value=2.0)
    b.add("t.Touch", "write", path="out.txt")
    b.connect("s.out", "write.x")
    b.output("img", "s.out")
    b.output("file", "write.path")
    g = b.build()
    session.run(g, outputs=["img"])
    assert not (tmp_path / "out.txt").exists()
    out = session.run(g, outputs=["file"])
    assert out["file"] == str(tmp_path / "out.txt") and (tmp_path / "out.txt").read_text() == "32.0"
    (tmp_path / "out.txt").unlink()
    session.run(g, outputs=["file"])
    assert (tmp_path / "out.txt").exists() and calls.count("write") == 2


def test_device_opened_only_when_a_node_touches_it(session, calls):
    b = session.builder()
    b.add("t.Source", "s")
    b.add("t.UsesDevice", "d")
    b.output("o", "s.out")
    b.output("dev", "d.name")
    session.run(b.build(), outputs=["o"])
    assert not session.device_opened
    name = session.run(b.build(), outputs=["dev"])["dev"]
    assert session.device_opened and isinstance(name, str) and name


def test_request_by_node_output_ref_and_unknown_output(session, calls):
    g = diamond(session)
    assert session.run(g, outputs=["a.out"])["a.out"][0, 0] == 3.0
    with pytest.raises(GraphError, match="no output named 'nope'"):
        session.run(g, outputs=["nope"])
    with pytest.raises(GraphError, match="no such node output"):
        session.run(g, outputs=["a.nothing"])


def test_long_chain_does_not_recurse(calls):
    s = Session(registry=make_registry(calls), cache_bytes=1 << 26)
    b = s.builder()
    b.add("t.Source", "n0", value=0.0, size=1)
    for i in range(1, 3000):
        b.add("t.Add", f"n{i}", k=1.0)
        b.connect(f"n{i - 1}.out", f"n{i}.a")
    b.output("end", "n2999.out")
    assert s.run(b.build())["end"][0, 0] == 2999.0


def test_context_log_and_graph_dir(session, calls, tmp_path):
    b = session.builder(base_dir=str(tmp_path))
    b.add("t.Where", "w")
    b.output("f", "w.folder")
    seen = []
    assert session.run(b.build(), on_event=seen.append)["f"] == str(tmp_path)
    logs = [e for e in seen if isinstance(e, E.NodeLog)]
    assert logs == [E.NodeLog("w", f"resolving against {tmp_path}")]


def test_outputs_are_read_only_so_cached_values_cannot_be_corrupted(session, calls):
    g = diamond(session)
    out = session.run(g, outputs=["a.out"])["a.out"]
    with pytest.raises(ValueError, match="read-only"):
        out[0, 0] = 99.0


def test_warm_plans_give_the_keys_and_params_of_a_fresh_engine(calls):
    """The engine remembers what it planned for nodes that read no file; across a
    random walk of param edits and a scaled plan, every key and every param a node
    gets equal those of a new engine planning the same graph from nothing."""
    import random

    rng = random.Random(3)
    warm = Session(registry=make_registry(calls), cache_bytes=1 << 26)
    g = diamond(warm)
    for step in range(40):
        edits = {f"{rng.choice(['a', 'b2', 'top', 'other2'])}.k": float(rng.randrange(4)),
                 "src.value": float(rng.randrange(3)), "s1.factor": rng.choice([1.0, 3.0])}
        g = warm.graph(g, edits)
        scale = rng.choice([1.0, 0.5])
        fresh = Session(registry=make_registry([]), cache_bytes=1 << 26)
        pw, pf = warm.plan(g, scale=scale), fresh.plan(g, scale=scale)
        assert pw.keys == pf.keys
        assert pw.params == pf.params
        if step % 10 == 0:
            assert float(warm.run(g)["final"][0, 0]) == float(fresh.run(g)["final"][0, 0])
