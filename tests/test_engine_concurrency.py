"""Independent branches run concurrently when the session has workers, device nodes
one at a time; results, caching and errors are those of an in-order run. Proved with
barriers (both branches must be inside compute together), never with timing."""
import threading

import numpy as np
import pytest

from engine_testnodes import T, make_registry
from pixgraph.errors import NodeError
from pixgraph.node import Node, node, param, port
from pixgraph.session import Session


def _nodes(barrier, device_seen, active):
    @node("tc.Meet", version=1)
    class Meet(Node):
        """Waits at the barrier: two of these finish only if they run at once."""
        class Inputs:
            x: T.Image = port()
        class Params:
            k: float = param(1.0)
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            barrier.wait()
            return {"out": (inputs.x + np.float32(params.k)).astype(np.float32)}

    @node("tc.Dev", version=1)
    class Dev(Node):
        """Opens the device and records how many nodes hold it at once."""
        class Inputs:
            x: T.Image = port()
        class Params:
            k: float = param(1.0)
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            ctx.device
            with active["lock"]:
                active["now"] += 1
                device_seen.append(active["now"])
                active["entered"] += 1
                if active["entered"] >= 2:
                    active["both"].set()
            # give another branch every chance to get in: the first one in waits until
            # the second has entered (only with a broken device lock) or 0.5 s
            active["both"].wait(0.5)
            with active["lock"]:
                active["now"] -= 1
            return {"out": (inputs.x + np.float32(params.k)).astype(np.float32)}

    return [Meet, Dev]


def _session(workers, barrier=None, seen=None, calls=None):
    reg = make_registry(calls if calls is not None else [])
    for cls in _nodes(barrier or threading.Barrier(2, timeout=30), seen if seen is not None else [],
                      {"lock": threading.Lock(), "now": 0, "entered": 0, "both": threading.Event()}):
        reg.add(cls)
    return Session(registry=reg, workers=workers)  # the device is the session's OpenCL one (PoCL here)


def _branches(s, type_id, n=2):
    b = s.builder()
    b.add("t.Source", "src", value=1.0)
    for i in range(n):
        b.add(type_id, f"br{i}", k=float(i))
        b.connect("src.out", f"br{i}.x")
    b.add("t.Add", "join")
    b.connect("br0.out", "join.a")
    b.connect("br1.out", "join.b")
    b.output("o", "join.out")
    return b.build()


def test_independent_branches_run_at_once():
    s = _session(workers=2)
    r = s.run(_branches(s, "tc.Meet"))  # an in-order run would wait at the barrier until it broke
    assert float(r["o"][0, 0]) == (1 + 0) + (1 + 1)
    assert set(r.ran) == {"src", "br0", "br1", "join"} and r.ran[0] == "src" and r.ran[-1] == "join"


def test_in_order_by_default():
    s = _session(workers=None, barrier=threading.Barrier(2, timeout=0.5))
    assert s.engine.workers == 1
    with pytest.raises(NodeError, match="BrokenBarrierError"):
        s.run(_branches(s, "tc.Meet"))


def test_device_nodes_take_turns():
    seen = []
    s = _session(workers=4, seen=seen)
    r = s.run(_branches(s, "tc.Dev"))
    assert float(r["o"][0, 0]) == 3.0 and seen == [1, 1]


def test_same_results_and_cache_as_in_order():
    outs = []
    for workers in (1, 3):
        calls = []
        s = _session(workers=workers, barrier=threading.Barrier(1), calls=calls)
        g = _branches(s, "tc.Meet")
        first = s.run(g)
        again = s.run(g, params={"br1.k": 5.0})
        outs.append((float(first["o"][0, 0]), float(again["o"][0, 0]), sorted(again.ran)))
    assert outs[0] == outs[1] == (3.0, 7.0, ["br1", "join"])


def test_a_failing_branch_fails_the_run_naming_its_node():
    s = _session(workers=2)
    b = s.builder()
    b.add("t.Source", "src")
    b.add("t.Boom", "bomb")
    b.add("t.Add", "ok")
    b.connect("src.out", "ok.a")
    b.add("t.Add", "join")
    b.connect("ok.out", "join.a")
    b.connect("bomb.out", "join.b")
    b.output("o", "join.out")
    with pytest.raises(NodeError, match=r"node 'bomb' \(t.Boom\): failed: ZeroDivisionError: kaboom"):
        s.run(b.build())
