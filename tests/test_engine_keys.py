"""Every node type, present and future: each cache-relevant param and each input
changes the node's cache key, and params declared ``cache=False`` do not. A node
with an ``affects`` hook: exactly the params and inputs it names for the default
params change the key.

Keys are computed by ``plan()`` alone, so nothing runs: each input is fed by a stub
source node of the port's type, and each param is perturbed to another valid value.
"""
import pytest

from pixgraph.engine import Engine
from pixgraph.cache import MemoryCache
from pixgraph.graph import GraphBuilder
from pixgraph.node import Namespace, ParamSpec, node, param, port
from pixgraph.registry import Registry

ALL = Registry.discover()
#: discovery that finds nothing (an uninstalled checkout) must fail, not yield 0 tests
TYPE_IDS = list(ALL) or ["<no node types discovered>"]


def _stub(port_type):
    @node(f"stub.{port_type.type_name()}", version=1)
    class Stub:
        class Params:
            seed: int = param(0)
        class Outputs:
            out: port_type = port()

        def compute(self, ctx, inputs, params):  # never called: keys only
            raise AssertionError

    return Stub


def _other_value(p: ParamSpec, value):
    """A different valid value for ``p``, or None when there is none."""
    lo = p.min if p.min is not None else -1e9
    hi = p.max if p.max is not None else 1e9
    if p.kind == "bool":
        return not value
    if p.kind in ("int", "float"):
        step = 1 if p.kind == "int" else max(abs(value) * 0.5, 0.25)
        for cand in (value + step, value - step, (lo + hi) / 2):
            cand = int(cand) if p.kind == "int" else float(cand)
            if lo <= cand <= hi and cand != value:
                return cand
        return None
    if p.kind == "str":
        if p.choices:
            return next((c for c in p.choices if c != value), None)
        return value + "x"
    if p.kind == "floats":
        vals = list(value)
        if not vals:
            return None
        for cand in (vals[0] + 0.25, vals[0] - 0.25):
            if lo <= cand <= hi:
                return [cand] + vals[1:]
        return None
    return None


@pytest.mark.parametrize("type_id", TYPE_IDS)
def test_every_param_and_input_changes_the_key(type_id, tmp_path):
    assert type_id in ALL, ("Registry.discover() found no node types: install the checkout "
                            "(pip install -e .) so the pixgraph.nodes entry point exists")
    spec = ALL.get(type_id)
    affects = spec.cls().affects(Namespace(spec.coerce_params({}) if all(not q.required for q in spec.params)
                                           else {q.name: q.default for q in spec.params}))
    names = None if affects is None else set(affects)
    reg = Registry()
    reg.add(spec.cls)
    stubs = {}
    for p in spec.inputs:
        cls = stubs.setdefault(p.type, _stub(p.type))
        if cls.spec.type_id not in reg:
            reg.add(cls)
    (tmp_path / "in.bin").write_bytes(b"one")
    base = {p.name: ("in.bin" if not p.writes else "out.bin") for p in spec.params if p.kind == "path"}

    def key(params=None, seeds=None):
        b = GraphBuilder(reg, base_dir=str(tmp_path))
        b.add(type_id, "n", **{**base, **(params or {})})
        for p in spec.inputs:
            b.add(stubs[p.type].spec.type_id, f"in_{p.name}", seed=(seeds or {}).get(p.name, 0))
            b.connect(f"in_{p.name}.out", f"n.{p.name}")
        b.output("o", f"n.{spec.outputs[0].name}")
        return Engine(reg, MemoryCache(0)).plan(b.build(), bind=None).keys["n"]

    k0 = key()
    assert key() == k0  # deterministic
    for p in spec.params:
        if p.kind == "path":
            if p.writes:
                assert key({p.name: "other.bin"}) != k0, f"{type_id}: param {p.name} (written path)"
            else:
                (tmp_path / "in.bin").write_bytes(b"two")
                assert key() != k0, f"{type_id}: content of param {p.name}"
                (tmp_path / "in.bin").write_bytes(b"one")
            continue
        alt = _other_value(p, p.default)
        if alt is None:
            continue
        changed = key({p.name: alt}) != k0
        expect = p.cache and (names is None or p.name in names)
        assert changed == expect, f"{type_id}: param {p.name} = {alt!r} {'did not change' if expect else 'changed'} the key"
    for p in spec.inputs:
        expect = names is None or p.name in names
        assert (key(seeds={p.name: 1}) != k0) == expect, f"{type_id}: input {p.name}"


def test_discovery_found_the_engine_nodes():
    assert {"pixgraph.GaussianBlur", "pixgraph.Merge", "pixgraph.Constant"} <= set(ALL)
    assert len(ALL) >= 28 and ALL.errors == []
