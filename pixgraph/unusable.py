"""Outputs a node declares unusable for its params, refused before anything runs.

A node class may define ``unusable_outputs(self, node_id, params) -> {output:
reason}``, reading at most file headers: an output that exists in the
declaration but has no meaning for these params, e.g. ``LoadImage``'s
``alpha`` of a file without an alpha channel (all ones: a cutout covering the
whole frame). Any node that takes its input from such an output is refused with
the reason, naming that node and its input (``plan``, ``run``, ``explain`` and
``validate``), and the graph's other outputs still work. An error inside the hook
(say, a file that cannot be read) is left to the node's own compute to report.
"""
from __future__ import annotations

from typing import Any, Iterable, Mapping

from .graph import Graph
from .node import Namespace
from .registry import Registry


def refuse_unusable_inputs(graph: Graph, registry: Registry, nodes: Iterable[str],
                           params: Mapping[str, Mapping[str, Any]], bind: Mapping[str, Any]) -> None:
    """Raise ``GraphError`` (naming the node, its input, the file and line) when a
    node among ``nodes`` takes an input from an output its source declares
    unusable; ``params`` holds the checked params of the source nodes. Bound nodes
    (a host's array) are not asked: their outputs come from the array."""
    reasons: dict[str, dict[str, str]] = {}
    hooked: dict[str, bool] = {}  # node type -> declares the hook (most types do not)
    nodes_of = graph.nodes
    for nid in nodes:
        if nid in bind:
            continue
        for port, ref in nodes_of[nid].inputs.items():
            src = ref.node
            if src in bind or src not in params:
                continue
            if src not in reasons:
                t = nodes_of[src].type
                if t not in hooked:
                    hooked[t] = getattr(registry.get(t).cls, "unusable_outputs", None) is not None
                reasons[src] = _unusable(graph, registry, src, params[src]) if hooked[t] else {}
            why = reasons[src].get(ref.output)
            if why:
                raise graph.error(why, node=nid, field=f"inputs.{port}")


def _unusable(graph: Graph, registry: Registry, nid: str, params: Mapping[str, Any]) -> dict[str, str]:
    """The hook's ``{output: reason}`` (the caller checked that the class has one)."""
    cls = registry.get(graph.nodes[nid].type).cls
    try:
        out = cls().unusable_outputs(nid, Namespace(params))
    except Exception:  # noqa: BLE001 - the node's compute reports an unreadable file itself
        return {}
    return {str(k): str(v) for k, v in dict(out or {}).items()}
