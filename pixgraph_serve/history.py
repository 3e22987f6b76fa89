"""The undo history of the served graph: its states before each user action.

A state (``Step``) is a reference to an immutable ``Graph`` (node types, params and
wiring: never pixels; an edit builds a new graph and leaves the old one as it was)
and the params a type switch stashed, so a step costs a few kilobytes whatever the
size of the photo the graph reads. At most ``limit`` steps are kept, the oldest
dropped first.

One *user action* is one step: an edit carries the page's id of the action it belongs
to (``action``), and an edit with the action of the newest step continues that step
(a drag's previews and its final), so undo takes the whole drag back. An edit without
an action (a script's request) is a step of its own; an edit that changes nothing is
none; a new step drops the redo steps. Undo and redo end the action: the next edit
starts a step of its own whatever its id.

Nothing here knows node types or HTTP: ``ServeState.edit`` records, ``ServeState.undo``
and ``redo`` move, ``app.py`` answers.
"""
from __future__ import annotations

import dataclasses
from typing import Mapping

from pixgraph.graph import Graph

from .errors import ServeError

#: the most characters of an edit's ``action`` (the page's id of one user action)
MAX_ACTION = 200


@dataclasses.dataclass(frozen=True)
class Step:
    """A state of the graph: the graph and the params its type switches stashed
    (``ServeState.set_type``: (node, type) -> params)."""

    graph: Graph
    stash: Mapping[tuple[str, str], dict]


class History:
    """Undo and redo lists of ``Step``, at most ``limit`` to undo."""

    def __init__(self, limit: int):
        self.limit = max(1, int(limit))
        self.undo: list[Step] = []        # oldest first
        self.redo: list[Step] = []        # the next to redo last
        self.action: str | None = None    # the action of the newest undo step (None: ended)

    @staticmethod
    def check_action(action) -> None:
        if action is not None and (not isinstance(action, str) or len(action) > MAX_ACTION):
            raise ServeError(400, f"action must be a string of at most {MAX_ACTION} characters", field="action")

    def save(self) -> tuple:
        """What ``restore`` puts back (an edit that fails leaves the history as it was)."""
        return list(self.undo), list(self.redo), self.action

    def restore(self, saved: tuple) -> None:
        self.undo, self.redo, self.action = saved

    def record(self, before: Step, now: Graph, action: str | None) -> None:
        """An edit took the graph from ``before`` to ``now``: keep ``before`` as a step,
        unless nothing changed or ``action`` continues the newest step."""
        if now == before.graph:
            return
        if action is not None and action == self.action and self.undo:
            return
        self.undo.append(before)
        del self.undo[:-self.limit]
        self.redo.clear()
        self.action = action

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
        self.action = None

    def counts(self) -> dict:
        """``{"undo": steps, "redo": steps, "limit": limit}``."""
        return {"undo": len(self.undo), "redo": len(self.redo), "limit": self.limit}
