"""The graph value, its builder, and structural validation.

A ``Graph`` is immutable: nodes and outputs are read-only mappings, and every edit
goes through a ``GraphBuilder`` that produces a new, validated graph::

    b = GraphBuilder(registry)
    b.add("pixgraph.LoadImage", "load", path="cutout.png")
    b.add("pixgraph.GaussianBlur", "blur", sigma=3)
    b.connect("load.image", "blur.image")
    b.set("blur", sigma=4)
    b.output("final", "blur.image")
    g = b.build()                     # raises GraphError on the first problem

Connections are written ``"node.output"`` and point *into* an input:
``connect(src="load.image", dst="blur.image")``. Params are stored as the user
set them (after coercion); defaults are filled in by the engine, so a saved file
only lists what differs from the node's declaration.

Every validation error is a ``GraphError`` naming the node and the port or param,
and, for a graph read from a file, the file and line.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import re
from types import MappingProxyType
from typing import Any, Mapping

from .errors import MAX_ERROR_LINE, GraphError, PathError, one_line  # noqa: F401 (re-exported)
from .node import NodeSpec, ParamError
from .registry import Registry, UnknownNodeType

NODE_ID = re.compile(r"^[A-Za-z_][A-Za-z0-9_\-]*$")


@dataclasses.dataclass(frozen=True)
class Ref:
    """One output of one node, written ``"node.output"``."""

    node: str
    output: str

    @classmethod
    def parse(cls, text: Any) -> "Ref":
        if isinstance(text, Ref):
            return text
        if not isinstance(text, str) or text.count(".") != 1 or text.startswith(".") or text.endswith("."):
            raise ValueError(f"expected 'node.output', got {text!r}")
        node, output = text.split(".")
        return cls(node, output)

    def __str__(self) -> str:
        return f"{self.node}.{self.output}"


def split_param(name: Any, what: str = "param") -> tuple[str, str]:
    """``"light.azimuth"`` -> ``("light", "azimuth")``: the one parser of a
    ``node.param`` name (``--set``, overrides, manifest columns, sweeps, the page's
    edits). Raises ``GraphError`` naming ``what`` when it is not ``node.param``."""
    node, dot, pname = str(name).partition(".")
    if not isinstance(name, str) or not dot or not node or not pname:
        raise GraphError(f"{what} {name!r} must be 'node.param' or {{node: {{param: value}}}}"
                         if what == "param override" else f"{what} {name!r} must be 'node.param'")
    return node, pname


def _frozen(d: Mapping) -> Mapping:
    return MappingProxyType(dict(d))


@dataclasses.dataclass(frozen=True)
class NodeInstance:
    """A node in a graph: its id, type, the params set on it and its input connections."""

    id: str
    type: str
    params: Mapping[str, Any] = dataclasses.field(default_factory=lambda: _frozen({}))
    inputs: Mapping[str, Ref] = dataclasses.field(default_factory=lambda: _frozen({}))

    def __post_init__(self):
        object.__setattr__(self, "params", _frozen(self.params))
        object.__setattr__(self, "inputs", _frozen(self.inputs))


@dataclasses.dataclass(frozen=True)
class Graph:
    """An immutable graph: nodes by id, named outputs, and where it came from.

    ``file`` and ``lines`` (``"nodes.blur.params.sigma" -> 12``) only serve error
    messages, and ``base_dir`` resolves relative path params; none of the three
    takes part in equality.
    """

    nodes: Mapping[str, NodeInstance]
    outputs: Mapping[str, Ref]
    file: str | None = dataclasses.field(default=None, compare=False)
    base_dir: str = dataclasses.field(default="", compare=False)
    lines: Mapping[str, int] = dataclasses.field(default_factory=lambda: _frozen({}), compare=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "nodes", _frozen(self.nodes))
        object.__setattr__(self, "outputs", _frozen(self.outputs))
        object.__setattr__(self, "lines", _frozen(self.lines))
        object.__setattr__(self, "base_dir", os.path.abspath(self.base_dir or os.getcwd()))

    def resolve_path(self, path: str) -> str:
        """A path param made absolute against the graph file's folder."""
        return os.path.normpath(os.path.join(self.base_dir, os.path.expanduser(path)))

    def error(self, message: str, node: str | None = None, field: str | None = None) -> GraphError:
        """A GraphError with the line of the most specific location known."""
        line = None
        keys = []
        if node is not None:
            keys = [f"nodes.{node}.{field}" if field else None, f"nodes.{node}"]
            if field and "." in field:
                keys.insert(1, f"nodes.{node}.{field.split('.')[0]}")
        elif field is not None:
            keys = [field, field.split(".")[0]]
        for k in keys:
            if k is not None and k in self.lines:
                line = self.lines[k]
                break
        return GraphError(message, file=self.file, line=line, node=node, field=field)


def validate(graph: Graph, registry: Registry) -> Graph:
    """Check types, params, connections, required inputs and cycles.

    Returns the graph with params coerced to canonical form; raises the first
    ``GraphError`` in file order.
    """
    canonical = {}
    for nid, inst in graph.nodes.items():
        if not NODE_ID.match(nid):
            raise graph.error("node ids are letters, digits, '_' and '-' (no dots), "
                              "starting with a letter or '_'", node=nid)
        try:
            spec = registry.get(inst.type)
        except UnknownNodeType:
            hint = registry.suggest(inst.type)
            broken = (f"; {len(registry.errors)} node pack(s) failed to load, see 'pixgraph nodes --errors'"
                      if registry.errors else "")
            raise graph.error(f"unknown node type {inst.type!r}" + (f" (did you mean {hint!r}?)" if hint else "")
                              + broken, node=nid, field="type") from None
        params = _check_params(graph, nid, spec, inst.params)
        _check_inputs(graph, nid, spec, inst.inputs, registry)
        canonical[nid] = dataclasses.replace(inst, params=params)
    for name, ref in graph.outputs.items():
        _check_ref(graph, ref, None, f"outputs.{name}", registry)
    _check_cycles(graph)
    return dataclasses.replace(graph, nodes=canonical)


def _check_params(graph: Graph, nid: str, spec: NodeSpec, values: Mapping[str, Any]) -> dict:
    out = {}
    for name, value in values.items():
        p = spec.param(name)
        if p is None:
            known = ", ".join(q.name for q in spec.params) or "none"
            raise graph.error(f"unknown param (known: {known})", node=nid, field=f"params.{name}")
        try:
            out[name] = p.coerce(value)
        except ParamError as e:
            raise graph.error(e.message, node=nid, field=f"params.{name}") from None
        if p.kind == "path":
            from .paths import bad_characters

            why = bad_characters(os.fspath(out[name]))
            if why:
                e = graph.error(f"path {out[name]!r} {why}", node=nid, field=f"params.{name}")
                raise PathError(e.message, file=e.file, line=e.line, node=nid, field=e.field)
        if p.kind == "path" and not p.writes and not os.path.isfile(graph.resolve_path(out[name])):
            raise graph.error(f"file not found: {graph.resolve_path(out[name])}", node=nid, field=f"params.{name}")
    for p in spec.params:
        if p.required and p.name not in values:
            raise graph.error("is required and was not set", node=nid, field=f"params.{p.name}")
    return out


def _check_ref(graph: Graph, ref: Ref, nid: str | None, field: str, registry: Registry):
    src = graph.nodes.get(ref.node)
    if src is None:
        raise graph.error(f"refers to node {ref.node!r}, which is not in the graph", node=nid, field=field)
    if src.type not in registry:
        raise graph.error(f"refers to node {ref.node!r} of unknown type {src.type!r}", node=nid, field=field)
    out = registry.get(src.type).output(ref.output)
    if out is None:
        names = ", ".join(o.name for o in registry.get(src.type).outputs)
        raise graph.error(f"node {ref.node!r} has no output {ref.output!r} (outputs: {names})", node=nid, field=field)
    return out


def _check_inputs(graph: Graph, nid: str, spec: NodeSpec, inputs: Mapping[str, Ref], registry: Registry):
    for port_name, ref in inputs.items():
        p = spec.input(port_name)
        if p is None:
            names = ", ".join(i.name for i in spec.inputs) or "none"
            raise graph.error(f"unknown input (inputs: {names})", node=nid, field=f"inputs.{port_name}")
        out = _check_ref(graph, ref, nid, f"inputs.{port_name}", registry)
        if not p.type.accepts(out.type):
            raise graph.error(f"{ref} is {out.type.type_name()}, which cannot feed {p.type.type_name()}",
                              node=nid, field=f"inputs.{port_name}")
    for p in spec.inputs:
        if not p.optional and p.name not in inputs:
            raise graph.error(f"required input is not connected ({p.type.type_name()})",
                              node=nid, field=f"inputs.{p.name}")


def _check_cycles(graph: Graph) -> None:
    import networkx as nx

    index = {n: i for i, n in enumerate(graph.nodes)}
    if all(index.get(ref.node, -1) < index[nid] for nid, inst in graph.nodes.items()
           for ref in inst.inputs.values()):
        return  # every input comes from a node earlier in the file: no cycle is possible
    g = dag(graph)
    if nx.is_directed_acyclic_graph(g):  # linear; find_cycle alone is quadratic on long chains
        return
    # the first strongly connected component (file order) that holds a cycle, followed
    # along inputs so the path reads "a <- b <- a": a takes b's output
    comps = [c for c in nx.strongly_connected_components(g) if len(c) > 1 or g.has_edge(*[next(iter(c))] * 2)]
    comp = min(comps, key=lambda c: min(index[n] for n in c))
    start = min(comp, key=index.__getitem__)
    cycle = nx.find_cycle(g.subgraph(comp).reverse(copy=False), source=start)
    path = [u for u, _ in cycle] + [cycle[-1][1]]
    raise graph.error("cycle: " + " <- ".join(path), node=path[0])


# -- the graph as a networkx DiGraph ------------------------------------------------

def dag(graph: Graph):
    """``graph`` as a ``networkx.DiGraph``: one vertex per node id (file order), an
    edge ``src -> dst`` for each connection (attribute ``ports``: the list of
    ``(output, input)`` pairs it carries). Made on each call and not kept: a
    networkx graph is thousands of small dicts, and keeping one per graph value
    made Python's garbage collector several times slower for the whole process
    (benchmarks/engine_overhead.py). References to missing nodes are left out
    (``validate`` reports them)."""
    import networkx as nx

    ports: dict[tuple[str, str], list] = {}
    nodes = graph.nodes
    for nid, inst in nodes.items():
        for port, ref in inst.inputs.items():
            if ref.node in nodes:
                ports.setdefault((ref.node, nid), []).append((ref.output, port))
    g = nx.DiGraph()
    g.add_nodes_from(nodes)
    g.add_edges_from((a, b, {"ports": p}) for (a, b), p in ports.items())
    return g


def upstream(graph: Graph, roots, stop=()) -> list[str]:
    """``roots`` and every node they depend on, inputs before the nodes that use
    them (ties in file order); the inputs of nodes in ``stop`` (bound nodes) are
    not followed."""
    import networkx as nx

    memo = graph.__dict__.setdefault("_upstream", {})
    k = (tuple(roots), frozenset(stop))
    if k in memo:  # a graph is immutable: plan it again (a warm run) without the walk
        return list(memo[k])
    # an edited graph (new params, same connections) has the same order: remembered by
    # the digest of its structure, a few strings per process
    shape = hashlib.sha256(repr((k[0], sorted(k[1]), [(n, sorted((p, r.node) for p, r in i.inputs.items()))
                                                       for n, i in graph.nodes.items()])).encode()).hexdigest()
    if shape in _ORDERS:
        memo[k] = _ORDERS[shape]
        return list(memo[k])
    g = dag(graph)
    if stop:
        g = g.copy()
        g.remove_edges_from([e for n in stop if n in g for e in list(g.in_edges(n))])
    needed = set(roots)
    for r in roots:
        if r not in needed or len(needed) < len(g):
            needed |= nx.ancestors(g, r)
    sub = g if len(needed) == len(g) else g.subgraph(needed).copy()
    order = list(nx.topological_sort(sub))  # inputs first; ties in file order (insertion order)
    memo[k] = _ORDERS[shape] = tuple(order)
    if len(memo) > 64:
        memo.pop(next(iter(memo)))
    while len(_ORDERS) > 32:
        _ORDERS.pop(next(iter(_ORDERS)))
    return order


#: structure digest -> dependency order (``upstream``), the most recent 32
_ORDERS: dict[str, tuple[str, ...]] = {}


def downstream(graph: Graph, node_ids) -> set[str]:
    """Every node whose result depends on one of ``node_ids`` (exclusive): what an
    edit of those nodes can change."""
    import networkx as nx

    g = dag(graph)
    out: set[str] = set()
    for n in node_ids:
        out |= nx.descendants(g, n)
    return out


class GraphBuilder:
    """Mutable recipe for a ``Graph``; ``build()`` validates and freezes it."""

    def __init__(self, registry: Registry, *, base_dir: str | None = None, graph: Graph | None = None):
        """An empty builder, or one holding ``graph``'s nodes (``from_graph``)."""
        self.registry = registry
        self.base_dir = base_dir or (graph.base_dir if graph is not None else os.getcwd())
        self._nodes: dict[str, dict] = {}
        self._outputs: dict[str, Ref] = {}
        self._file: str | None = None
        self._lines: dict[str, int] = {}
        #: the graph this builder came from while only params changed (same nodes,
        #: connections and outputs): the built graph shares its remembered orders
        self._same_shape: Graph | None = graph
        if graph is not None:
            for nid, inst in graph.nodes.items():
                self._nodes[nid] = {"type": inst.type, "params": dict(inst.params), "inputs": dict(inst.inputs)}
            self._outputs = dict(graph.outputs)
            self._file, self._lines = graph.file, dict(graph.lines)

    @classmethod
    def from_graph(cls, graph: Graph, registry: Registry) -> "GraphBuilder":
        """A builder holding ``graph``'s nodes, to derive an edited graph from it."""
        return cls(registry, graph=graph)

    def add(self, type_id: str, node_id: str, **params: Any) -> str:
        """Add a node of type ``type_id``; returns ``node_id``."""
        if node_id in self._nodes:
            raise GraphError("a node with this id already exists", node=node_id)
        self._nodes[node_id] = {"type": type_id, "params": dict(params), "inputs": {}}
        self._same_shape = None
        return node_id

    def connect(self, src: str, dst: str) -> None:
        """Feed output ``src`` (``"node.output"``) into input ``dst`` (``"node.input"``)."""
        s, d = self._ref(src), self._ref(dst)
        self._node(d.node)["inputs"][d.output] = s
        self._same_shape = None

    def disconnect(self, dst: str) -> None:
        d = self._ref(dst)
        self._node(d.node)["inputs"].pop(d.output, None)
        self._same_shape = None

    def set(self, node_id: str, **params: Any) -> None:
        """Set params on a node (validated at ``build()``)."""
        self._node(node_id)["params"].update(params)
        for name in params:  # no longer the value on that line of the file
            self._lines.pop(f"nodes.{node_id}.params.{name}", None)

    def unset(self, node_id: str, *names: str) -> None:
        """Return params to their declared defaults."""
        for n in names:
            self._node(node_id)["params"].pop(n, None)

    def remove(self, node_id: str) -> None:
        self._node(node_id)
        del self._nodes[node_id]
        self._same_shape = None

    def output(self, name: str, ref: str) -> None:
        """Name an output of the graph: ``output("final", "comp.image")``."""
        self._outputs[name] = self._ref(ref)
        self._same_shape = None

    def build(self) -> Graph:
        g = Graph({nid: NodeInstance(nid, n["type"], n["params"], n["inputs"]) for nid, n in self._nodes.items()},
                  self._outputs, file=self._file, base_dir=self.base_dir, lines=self._lines)
        g = validate(g, self.registry)
        if self._same_shape is not None:  # an edit of params only: the same dependency orders
            g.__dict__["_upstream"] = self._same_shape.__dict__.setdefault("_upstream", {})
        return g

    def _node(self, node_id: str) -> dict:
        try:
            return self._nodes[node_id]
        except KeyError:
            raise GraphError("no such node in the graph", node=node_id) from None

    @staticmethod
    def _ref(text: str) -> Ref:
        try:
            return Ref.parse(text)
        except ValueError as e:
            raise GraphError(str(e)) from None
