"""What a plan and a run hand out: the context a node computes in, the plan's
steps, the plan, and a run's result (``Engine.plan``/``Engine.run``).
"""
from __future__ import annotations

import collections.abc
import dataclasses
import os
from typing import Any, Callable, Mapping

from . import events as E
from .graph import Graph, Ref
from .hashing import KeyParts


class NodeContext:
    """What a node's ``compute`` may use besides its inputs and params.

    ``device`` is opened on first access only, so graphs without OpenCL nodes
    never touch OpenCL. ``scale`` is the run's working resolution (``Engine.plan``):
    a node that declares ``uses_scale = True`` reads it (a loader makes its images
    this many times the file's size; see ``Node.uses_scale``); 1 is full size.
    """

    __slots__ = ("node_id", "graph_dir", "_device", "_cancel", "_emit", "scale")

    def __init__(self, node_id: str, graph_dir: str, device: Callable[[], Any],
                 cancel: E.CancelToken | None, emit: Callable[[Any], None], scale: float = 1.0):
        self.node_id = node_id
        self.graph_dir = graph_dir
        self.scale = scale
        self._device = device
        self._cancel = cancel
        self._emit = emit

    @property
    def device(self):
        """The session's ``pixgraph.device.Device``."""
        return self._device()

    def progress(self, fraction: float, message: str = "") -> None:
        """Report this node's progress, ``fraction`` in [0, 1]."""
        self._emit(E.NodeProgress(self.node_id, min(1.0, max(0.0, float(fraction))), message))

    def check_cancelled(self) -> None:
        """Raise ``events.Cancelled`` when the run was cancelled."""
        if self._cancel is not None:
            self._cancel.raise_if_cancelled()

    def log(self, message: str) -> None:
        self._emit(E.NodeLog(self.node_id, str(message)))


@dataclasses.dataclass(frozen=True)
class Step:
    """One needed node of a plan. ``status`` is run, memory, disk or bound."""

    node_id: str
    type_id: str
    key: str
    status: str
    reason: str


@dataclasses.dataclass(frozen=True)
class Plan:
    graph: Graph
    #: requested output name -> where it comes from
    outputs: Mapping[str, Ref]
    #: needed nodes, inputs before the nodes that use them
    steps: tuple[Step, ...]
    keys: Mapping[str, str]
    parts: Mapping[str, KeyParts]
    #: params as compute receives them: defaults filled in, paths absolute
    params: Mapping[str, Mapping[str, Any]]
    bind: Mapping[str, Any]
    #: bound node id -> its outputs (a host input's ``bind`` hook applied; else the
    #: array as the first output)
    bound: Mapping[str, Mapping[str, Any]] = dataclasses.field(default_factory=dict)
    #: working resolution of the run (1 = full size; see ``Engine.plan``)
    scale: float = 1.0

    def step(self, node_id: str) -> Step:
        return next(s for s in self.steps if s.node_id == node_id)

    def table(self) -> str:
        """The plan as a text table, for ``pixgraph explain``."""
        rows = [("node", "type", "status", "key", "why")]
        rows += [(s.node_id, s.type_id, s.status, s.key[:12], s.reason) for s in self.steps]
        widths = [max(len(r[i]) for r in rows) for i in range(4)]
        return "\n".join("  ".join(c.ljust(w) for c, w in zip(r[:4], widths)) + "  " + r[4] for r in rows)


@dataclasses.dataclass(frozen=True)
class RunResult(collections.abc.Mapping):
    """What a run returns: its outputs, and what ran and what came from a cache.

    It is a read-only mapping of output name -> value (``result["final"]``,
    ``dict(result)``, ``result.items()``); ``outputs`` is the same as a plain dict.
    """

    #: ``{output name: value}``
    outputs: dict[str, Any]
    #: compute seconds of each node that ran
    timings: dict[str, float]
    ran: tuple[str, ...]
    cached: tuple[str, ...]
    plan: Plan
    #: messages each node that ran logged (``ctx.log``), by node id
    logs: dict[str, list[str]] = dataclasses.field(default_factory=dict)
    #: what each node of the plan said when it made the result this run returns: its
    #: ``logs`` for a node that ran, and for one served from a cache what it logged when
    #: it ran with that key (while the engine remembers it); nodes that said nothing are absent
    said: dict[str, list[str]] = dataclasses.field(default_factory=dict)

    @property
    def seconds(self) -> float:
        """Compute seconds of the nodes that ran, summed (cache hits count 0)."""
        return float(sum(self.timings.values()))

    def __getitem__(self, name: str) -> Any:
        return self.outputs[name]

    def __iter__(self):
        return iter(self.outputs)

    def __len__(self) -> int:
        return len(self.outputs)


def files_upstream(plan: Plan, nid: str) -> str:
    """``"mask: 'small.png' (node 'cutout'), ..."``: for each input of a node, the files
    read by its nearest ancestors that read files, so an error names the user's files."""
    graph = plan.graph
    out = []
    for port, ref in graph.nodes[nid].inputs.items():
        seen, stack, files = set(), [ref.node], []
        while stack:
            n = stack.pop()
            if n in seen:
                continue
            seen.add(n)
            paths = [v for k, v in plan.parts[n].params.items() if isinstance(v, dict) and "file_sha256" in v] \
                if n in plan.parts else []
            if paths:
                for p in plan.params.get(n, {}).values():
                    if isinstance(p, str) and os.path.isfile(p):
                        files.append(f"{short_path(p)!r} (node {n!r})")
                continue
            if n in plan.bind:
                files.append(f"the array bound to {n!r}")
                continue
            stack.extend(r.node for r in graph.nodes[n].inputs.values())
        if files:
            out.append(f"{port}: {', '.join(dict.fromkeys(files))}")
    return "; ".join(out)


def short_path(path: str) -> str:
    """A path as short as it is clear: relative to the current folder when inside it."""
    rel = os.path.relpath(path)
    return path if rel.startswith("..") else rel
