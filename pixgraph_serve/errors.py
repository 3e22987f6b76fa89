"""The server's errors: ``ServeError`` and the one table that maps every other
exception a request can raise to its HTTP status.

Every refused request is answered as JSON ``{"error": "...", "node", "field",
"file", "line"}`` (the last four when known). ``status_of`` is the only place
that decides a status; ``app.py`` and ``state.py`` raise or translate through it.
"""
from __future__ import annotations

from typing import Any

from pixgraph.engine import NodeError, NodeInputError
from pixgraph.events import Cancelled
from pixgraph.graph import GraphError
from pixgraph.paths import PathError


class ServeError(Exception):
    """A request that cannot be served: HTTP ``status`` and a one-line message,
    with the node, field, file and line when known."""

    def __init__(self, status: int, message: str, **where: Any):
        super().__init__(message)
        self.status = status
        self.message = str(message).splitlines()[0] if message else "error"
        self.where = {k: v for k, v in where.items() if v is not None}

    def to_json(self) -> dict:
        return {"error": self.message, **self.where}


class RunTimeout(Exception):
    """A run stopped by the server's wall-clock limit (``--run-timeout``)."""


#: exception class -> HTTP status; the first matching row (in order) wins
STATUS = (
    (PathError, 403),         # a path outside the allowed folders (a GraphError: before it)
    (GraphError, 400),        # bad graph, param, output name
    (NodeInputError, 400),    # a node refused inputs that do not fit together
    (NodeError, 422),         # a node failed on the edited graph
    (RunTimeout, 503),        # over the server's time limit per run
    (Cancelled, 503),         # stopped: the server is shutting down
    (RecursionError, 400),    # input nested too deeply to parse
    (UnicodeDecodeError, 400),
)


def status_of(exc: BaseException) -> int | None:
    """The HTTP status of an exception the table knows, else None (a 500)."""
    for cls, status in STATUS:
        if isinstance(exc, cls):
            return status
    return None


def serve_error(exc: BaseException) -> ServeError:
    """``exc`` as a ``ServeError``; an exception the table does not know is a 500."""
    if isinstance(exc, ServeError):
        return exc
    status = status_of(exc) or 500
    where: dict[str, Any] = {}
    if isinstance(exc, GraphError):
        where = {"node": exc.node, "field": exc.field, "file": exc.file, "line": exc.line}
    elif isinstance(exc, NodeError):
        where = {"node": exc.node_id}
    if isinstance(exc, RecursionError):
        msg = "request nested too deeply"
    elif isinstance(exc, (RunTimeout, Cancelled)):
        msg = str(exc) or type(exc).__name__
    elif status == 500:
        msg = f"internal error: {type(exc).__name__}: {exc}"
    else:
        msg = str(exc)
    return ServeError(status, msg, **where)
