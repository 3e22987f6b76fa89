"""The undo history of the served graph: its states before each user action.

A state (``Step``) is a reference to an immutable ``Graph`` (node types, params and
wiring: never pixels; an edit builds a new graph and leaves the old one as it was)
and the params a type switch stashed, so a step costs a few kilobytes whatever the
size of the photo the graph reads: but a graph of thousands of nodes (a posted graph
may hold 200,000 values) is megabytes, and edits share none of it (an 8,000-node
graph loaded from YAML holds 13.3 MiB, by tracemalloc in
``benchmarks/serve_bounds_bench.py``). So at most ``limit`` steps are kept, and at
most ``max_bytes`` of them by ``graph_bytes`` (undo and redo together), the oldest
dropped first; the newest step is kept whatever its size.

One *user action* is one step: an edit carries the page's id of the action it belongs
to (``action``) and of the page that sent it (``client``), and an edit of an action
already in the newest step continues that step (a drag's previews and its final), so
undo takes the whole drag back. An edit without an action (a script's request) is a
step of its own; an edit that changes nothing is none; a new step drops the redo
steps. Undo and redo end every action: the next edit starts a step of its own
whatever its id.

**Two clients.** The graph is shared, so is the history: undo takes back the newest
step, whichever client made it. Actions of two clients that overlap in time (two tabs
dragging at once: their edits interleave) are one step: an edit of an action whose
step is not the newest (another client's step came since, while this action went on)
joins every step from its own to the newest into one, the state before the first of
them. So no step boundary falls inside any client's drag, and undo and redo only go
to states between actions, never to one with half a drag in it. Actions are told
apart by client and id: two clients may use the same id.

A step keeps at most ``MAX_STEP_ACTIONS`` actions (those that continued it last): a
client sending a new id with every edit while another's drag goes on cannot grow the
history past ``limit`` steps of that many ids. An action dropped so is one that has
not continued the step for that many others' actions; its next edit (if any) starts a
step of its own.

Nothing here knows node types or HTTP: ``ServeState.edit`` records, ``ServeState.undo``
and ``redo`` move, ``app.py`` answers.
"""
from __future__ import annotations

import dataclasses
import functools
from typing import Mapping

from pixgraph.graph import Graph

from .errors import ServeError

#: the most characters of an edit's ``action`` (the page's id of one user action) and ``client``
MAX_ACTION = 200

#: the most actions one undo step keeps (the newest to continue it): bounds the
#: history's ids however many actions join one step
MAX_STEP_ACTIONS = 32

#: one action: (client, action id); client None for a request without one
Key = tuple


#: estimated bytes of a graph's parts (``graph_bytes``), a little above what CPython
#: 3.11 holds (tracemalloc: 1,000 Constant nodes of 3 params, 1.6 MiB with their
#: lines, ``serve_bounds_bench.py --nodes 1000``; ``tests/test_serve_undo_bytes.py`` checks the estimate is not below it)
NODE_BYTES = 900        # a NodeInstance, its two mapping proxies and dicts, its entry
ITEM_BYTES = 160        # a param or input entry, a ``lines`` entry (key string and int)
VALUE_BYTES = 40        # a number, or a list or string's header


def value_bytes(v) -> int:
    """Estimated bytes of a param value (nested lists and dicts, strings by length)."""
    if isinstance(v, (str, bytes)):
        return VALUE_BYTES + len(v)
    if isinstance(v, Mapping):
        return VALUE_BYTES + sum(ITEM_BYTES + value_bytes(x) for x in v.values())
    if isinstance(v, (list, tuple)):
        return VALUE_BYTES + sum(8 + value_bytes(x) for x in v)
    return VALUE_BYTES


def graph_bytes(graph: Graph) -> int:
    """Estimated bytes a graph holds (its nodes, params, inputs and source lines), for
    the byte bounds of the undo history and the run records [bytes]. Linear in the
    graph's size: 49-131 ms for 8,000 nodes on 2 Xeon CPUs at load 2.5-3.4 (two
    runs of ``benchmarks/serve_bounds_bench.py``)."""
    total = NODE_BYTES * (len(graph.nodes) + len(graph.outputs)) + ITEM_BYTES * len(graph.lines)
    for inst in graph.nodes.values():
        total += len(inst.id) + ITEM_BYTES * len(inst.inputs)
        for v in inst.params.values():
            total += ITEM_BYTES + value_bytes(v)
    return total


@dataclasses.dataclass(frozen=True)
class Step:
    """A state of the graph: the graph and the params its type switches stashed
    (``ServeState.set_type``: (node, type) -> params)."""

    graph: Graph
    stash: Mapping[tuple[str, str], dict]

    @functools.cached_property
    def bytes(self) -> int:
        """Estimated bytes held (``graph_bytes`` and the stashed params) [bytes]."""
        return graph_bytes(self.graph) + sum(ITEM_BYTES + value_bytes(p) for p in self.stash.values())


class History:
    """Undo and redo lists of ``Step``, at most ``limit`` to undo and ``max_bytes`` in
    all (the newest step kept whatever its size)."""

    def __init__(self, limit: int, max_bytes: int = 64 << 20):
        self.limit = max(1, int(limit))
        self.max_bytes = int(max_bytes)
        self.undo: list[Step] = []        # oldest first
        self.redo: list[Step] = []        # the next to redo last
        #: the actions of each undo step still going on, the newest to continue it last
        #: (parallel to ``undo``, at most ``MAX_STEP_ACTIONS`` each; emptied by an undo or
        #: redo, which ends every action)
        self.actions: list[tuple[Key, ...]] = []

    @staticmethod
    def check_action(action, client=None) -> None:
        for name, v in (("action", action), ("client", client)):
            if v is not None and (not isinstance(v, str) or len(v) > MAX_ACTION):
                raise ServeError(400, f"{name} must be a string of at most {MAX_ACTION} characters", field=name)

    def save(self) -> tuple:
        """What ``restore`` puts back (an edit that fails leaves the history as it was)."""
        return list(self.undo), list(self.redo), list(self.actions)

    def restore(self, saved: tuple) -> None:
        self.undo, self.redo, self.actions = (list(x) for x in saved)

    def record(self, before: Step, now: Graph, action: str | None, client: str | None = None) -> None:
        """An edit of ``client``'s ``action`` took the graph from ``before`` to ``now``: keep
        ``before`` as a step, unless nothing changed or the action continues a step; when
        that step is not the newest (another client's steps came since), it and the newer
        steps become one (the module doc, "Two clients")."""
        if now == before.graph:
            return
        key = (client, action)
        if action is not None:
            own = next((i for i in range(len(self.actions) - 1, -1, -1) if key in self.actions[i]), None)
            if own is not None:
                # this action continues its step: it and the newer steps are one now, with
                # this action the newest of its actions
                joined = [k for keys in self.actions[own:] for k in keys if k != key] + [key]
                self.actions[own:] = [tuple(joined[-MAX_STEP_ACTIONS:])]
                del self.undo[own + 1:]
                return
        self.undo.append(before)
        self.actions.append(() if action is None else (key,))
        self.redo.clear()
        keep, held = 0, 0
        for step in reversed(self.undo[-self.limit:]):
            held += step.bytes
            if keep and held > self.max_bytes:
                break
            keep += 1
        del self.undo[:-keep]
        del self.actions[:-keep]

    def bytes(self) -> int:
        """Estimated bytes the undo and redo steps hold [bytes]."""
        return sum(s.bytes for s in (*self.undo, *self.redo))

    def peek(self, what: str) -> Step:
        """The state an ``undo`` or ``redo`` goes to; 409 when there is none."""
        source = self.undo if what == "undo" else self.redo
        if not source:
            raise ServeError(409, f"nothing to {what}: the history has {len(self.undo)} step(s) to undo "
                                  f"and {len(self.redo)} to redo", field=what)
        return source[-1]

    def moved(self, what: str, left: Step) -> None:
        """The graph went to ``peek(what)``'s state, leaving ``left``: the other list keeps it."""
        source, dest = (self.undo, self.redo) if what == "undo" else (self.redo, self.undo)
        source.pop()
        dest.append(left)
        self.actions = [()] * len(self.undo)

    def counts(self) -> dict:
        """``{"undo": steps, "redo": steps, "limit": limit}`` (the most steps; fewer are
        kept of graphs over ``max_bytes / limit``)."""
        return {"undo": len(self.undo), "redo": len(self.redo), "limit": self.limit}
