"""The node base: every hook declared once on ``Node`` with one signature, found by
declaration (``spec.hooks``), and the ``affects`` key hook that keeps params a node
ignores in its current mode out of its cache key."""
import numpy as np
import pytest

from engine_testnodes import T, make_registry
from pixgraph.errors import NodeError
from pixgraph.node import HOOKS, Namespace, Node, node, param, port
from pixgraph.registry import Registry
from pixgraph.session import Session


def _declare(body: dict, base=(Node,)):
    ns = {"__doc__": "A test node.", "__module__": __name__,
          "Outputs": type("Outputs", (), {"__annotations__": {"out": T.Image}, "out": port()}),
          "compute": lambda self, ctx, inputs, params: {"out": np.zeros((1, 1), np.float32)}}
    ns.update(body)
    return node("tb.N", version=1)(type("N", base, ns))


def test_hooks_are_found_by_declaration():
    assert HOOKS == ("compute", "infer", "bind", "describe", "affects")
    plain = _declare({})
    assert plain.spec.hooks == {"compute"}
    both = _declare({"describe": lambda self, params: "x", "infer": lambda self, ctx, inputs, params: {}})
    assert both.spec.hooks == {"compute", "describe", "infer"}
    # defaults, from the base
    assert plain().describe(Namespace({})) is None and plain().affects(Namespace({})) is None
    assert plain().bind(np.ones((2, 2), np.float32), Namespace({}))["out"].shape == (2, 2)


def test_a_plain_class_gets_the_base():
    @node("tb.Plain", version=1)
    class Plain:
        """No base named."""
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            return {"out": np.zeros((1, 1), np.float32)}

    assert issubclass(Plain, Node) and Plain.spec.hooks == {"compute"} and Plain.__name__ == "Plain"
    assert Plain.spec.disk_cache is True and Plain.spec.side_effects is False and Plain.preview is None


def test_hooks_with_another_signature_are_refused():
    with pytest.raises(TypeError, match=r"hook 'describe' must be a plain method describe\(self, params\)"):
        _declare({"describe": staticmethod(lambda params: "x")})
    with pytest.raises(TypeError, match=r"hook 'infer' must take \(self, ctx, inputs, params\), got \(self, ctx\)"):
        _declare({"infer": lambda self, ctx: {}})
    with pytest.raises(TypeError, match="needs a compute"):
        node("tb.NoCompute", version=1)(type("X", (Node,), {
            "Outputs": type("Outputs", (), {"__annotations__": {"out": T.Image}, "out": port()})}))


def _mode_nodes(calls):
    @node("tb.Mode", version=1)
    class Mode(Node):
        """mode 'a' outputs a + k_a (the b input and k_b unused); mode 'b' outputs b + k_b."""
        class Inputs:
            a: T.Image = port()
            b: T.Image = port()
        class Params:
            mode: str = param("a", choices=["a", "b"])
            k_a: float = param(0.0)
            k_b: float = param(0.0)
        class Outputs:
            out: T.Image = port()

        def affects(self, params):
            return {"mode", "a", "k_a"} if params.mode == "a" else {"mode", "b", "k_b"}

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            src, k = (inputs.a, params.k_a) if params.mode == "a" else (inputs.b, params.k_b)
            return {"out": (src + np.float32(k)).astype(np.float32)}

    @node("tb.Bad", version=1)
    class Bad(Node):
        """affects names a param it does not have."""
        class Outputs:
            out: T.Image = port()

        def affects(self, params):
            return {"nope"}

        def compute(self, ctx, inputs, params):
            return {"out": np.zeros((1, 1), np.float32)}

    return Mode, Bad


def _mode_session() -> Session:
    """A session with the test nodes and ``tb.Mode``/``tb.Bad``."""
    calls = []
    reg = make_registry(calls)
    for cls in _mode_nodes(calls):
        reg.add(cls)
    return Session(registry=reg)


def test_ignored_params_and_inputs_leave_downstream_cached():
    s = _mode_session()
    b = s.builder()
    b.add("t.Source", "sa", value=1.0)
    b.add("t.Source", "sb", value=2.0)
    b.add("tb.Mode", "m", mode="a", k_a=0.5)
    b.add("t.Add", "down", k=1.0)
    b.connect("sa.out", "m.a")
    b.connect("sb.out", "m.b")
    b.connect("m.out", "down.a")
    b.output("o", "down.out")
    g = b.build()
    first = s.run(g)
    assert float(first["o"][0, 0]) == 2.5
    # k_b and the b input are ignored in mode a: nothing downstream reruns
    r = s.run(g, params={"m.k_b": 9.0, "sb.value": 7.0})
    assert "m" not in r.ran and "down" not in r.ran and float(r["o"][0, 0]) == 2.5
    assert r.ran == ()  # m is served from cache, so sb is not even needed
    # a param the mode uses reruns the node and what follows
    r = s.run(g, params={"m.k_a": 1.5})
    assert set(r.ran) == {"m", "down"} and float(r["o"][0, 0]) == 3.5
    # switching the mode brings b and k_b in
    r = s.run(g, params={"m.mode": "b", "m.k_b": 0.25})
    assert {"m", "down"} <= set(r.ran) and float(r["o"][0, 0]) == 3.25


def test_affects_may_only_name_what_the_node_declares():
    s = _mode_session()
    b = s.builder()
    b.add("tb.Bad", "bad")
    b.output("o", "bad.out")
    with pytest.raises(NodeError, match=r"node 'bad' \(tb.Bad\): affects\(\) names no param or input \['nope'\]"):
        s.run(b.build())


def test_light_placed_by_shadow_tip_ignores_azimuth_downstream():
    """Gaffer's 'affects' on the real Light: under placement shadow_tip, azimuth and
    elevation change nothing, so the light and what uses it stay cached."""
    from pixgraph_nodes import types as NT

    calls = []

    @node("tb.UseLight", version=1)
    class UseLight(Node):
        """Counts its runs; outputs the light's position as a (1, 3) image."""
        class Inputs:
            light: NT.Light = port()
        class Outputs:
            out: NT.Image = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"out": np.asarray(inputs.light.position, np.float32).reshape(1, 3)}

    reg = Registry.discover()
    reg.add(UseLight)
    s = Session(registry=reg)
    b = s.builder()
    b.add("pixgraph.Camera", "cam", width=64, height=64, horizon=10.0)
    b.add("pixgraph.Light", "light", placement="shadow_tip", kind="point", tip_uv=[20.0, 50.0],
          top_uvh=[32.0, 30.0, 20.0], target_mode="pixel")
    b.add("tb.UseLight", "use")
    b.connect("cam.camera", "light.camera")
    b.connect("light.light", "use.light")
    b.output("o", "use.out")
    g = b.build()
    pos = s.run(g)["o"].copy()
    assert calls == ["use"]
    r = s.run(g, params={"light.azimuth": 140.0, "light.elevation": 10.0, "light.target_uv": [5.0, 60.0]})
    assert r.ran == () and calls == ["use"]
    np.testing.assert_array_equal(r["o"], pos)
    # the handles it does use rerun both
    r = s.run(g, params={"light.tip_uv": [10.0, 55.0]})
    assert set(r.ran) == {"light", "use"} and not np.array_equal(r["o"], pos)
    # placed by controls, azimuth is in the key again
    r1 = s.run(g, params={"light.placement": "controls"})
    r2 = s.run(g, params={"light.placement": "controls", "light.azimuth": 140.0})
    assert "light" in r2.ran and not np.array_equal(r1["o"], r2["o"])


def test_disk_cache_false_keeps_results_in_memory_only(tmp_path):
    calls = []

    @node("tb.Cheap", version=1)
    class Cheap(Node):
        """Large and cheap: not worth the disk."""
        disk_cache = False
        class Outputs:
            out: T.Image = port()

        def compute(self, ctx, inputs, params):
            calls.append(ctx.node_id)
            return {"out": np.ones((2, 2), np.float32)}

    reg = make_registry(calls)
    reg.add(Cheap)
    b = Session(registry=reg).builder()
    b.add("tb.Cheap", "cheap")
    b.add("t.Add", "add")
    b.connect("cheap.out", "add.a")
    b.output("o", "add.out")
    g = b.build()
    s = Session(registry=reg, disk_cache=str(tmp_path / "c"))
    plan = s.plan(g)
    s.run(g)
    assert plan.keys["add"] in s.disk and plan.keys["cheap"] not in s.disk
    assert Cheap.spec.disk_cache is False
    # a new process (a fresh session on the same disk cache) reads add from disk, never needs cheap
    s2 = Session(registry=reg, disk_cache=str(tmp_path / "c"))
    r = s2.run(g)
    assert r.ran == () and calls == ["cheap", "add"]
