"""Every error pixgraph reports, with its exit code and HTTP status in one place.

The shells (``pixgraph`` CLI, ``pixgraph_serve``, ``pixgraph_batch``) map an
exception to what they report with ``exit_code(exc)`` / ``http_status(exc)``
and ``message(exc)`` (one line), instead of each keeping its own table:

===================  ====  ====  ==============================================
class                exit  HTTP  meaning
===================  ====  ====  ==============================================
``GraphError``       2     400   the graph (file, line, node, field) cannot run
``PathError``        2     403   a path the policy refuses (a ``GraphError``)
``UsageError``       2     400   a bad command-line flag or request field
``InputError``       2     422   raised by a node: its inputs/params do not fit
``NodeInputError``   2     422   the engine's report of an ``InputError``, or of
                                 a node that ran out of memory, naming the node
``NodeError``        1     500   a node failed (a bug, not the user's input)
``Cancelled``        130   499   the run was cancelled (Ctrl-C, a client left)
``MemoryError``      2     507   the machine has too little memory for the
                                 sizes asked for (the message says what to lower)
anything else        1     500   internal failure
===================  ====  ====  ==============================================

``CacheError`` (``pixgraph.cache``: a cache folder that is not pixgraph's, a
negative limit) is a ``PixgraphError`` with exit 2 and HTTP 500 (the server's
own configuration). ``Cancelled`` stays in ``pixgraph.events`` and
``DeviceError`` in ``pixgraph.device`` (a device spec that matches nothing is bad
input, exit 2; a device that fails is exit 1); both are mapped here.
"""
from __future__ import annotations

EXIT_OK, EXIT_INTERNAL, EXIT_BAD_INPUT, EXIT_CANCELLED = 0, 1, 2, 130

#: longest error line printed, in characters
MAX_ERROR_LINE = 300


def one_line(text: str, limit: int = MAX_ERROR_LINE) -> str:
    """``text`` on one line, cut to ``limit`` characters (error messages quote user
    values, which may be huge)."""
    text = " ".join(str(text).split("\n"))
    return text if len(text) <= limit else text[:limit - 3] + "..."


class PixgraphError(Exception):
    """Base of pixgraph's own errors: ``exit_code`` for the CLI, ``http_status``
    for the server."""

    exit_code: int = EXIT_INTERNAL
    http_status: int = 500


class GraphError(PixgraphError, ValueError):
    """A graph that cannot run: names the node and field, and the file and line.

    ``field`` is a dotted path inside the node: ``"params.sigma"``,
    ``"inputs.image"``, ``"type"``, or for graph outputs ``"outputs.final"``.
    ``str()`` is one line: ``"g.yaml:12: node 'blur': param 'sigma': ..."``.
    """

    exit_code = EXIT_BAD_INPUT
    http_status = 400

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 node: str | None = None, field: str | None = None):
        super().__init__(message)
        self.message = message
        self.file = file
        self.line = line
        self.node = node
        self.field = field

    def __str__(self) -> str:
        parts = []
        if self.file:
            parts.append(f"{self.file}:{self.line}" if self.line else self.file)
        if self.node:
            parts.append(f"node {self.node!r}")
        if self.field and self.field != "type":
            head, _, rest = self.field.partition(".")
            label = {"params": "param", "inputs": "input", "outputs": "output"}.get(head)
            parts.append(f"{label} {rest!r}" if label and rest else self.field)
        parts.append(self.message)
        return one_line(": ".join(parts))


class PathError(GraphError):
    """A file path that the policy refuses (bad input: the CLI exits 2)."""

    http_status = 403


class UsageError(PixgraphError, ValueError):
    """Bad command-line input or request field (exit 2)."""

    exit_code = EXIT_BAD_INPUT
    http_status = 400


class InputError(PixgraphError, ValueError):
    """Raised by ``compute`` (or ``infer``/``bind``) when its inputs or params do not
    fit together (say, a mask and a pixel-height map of different sizes): the
    user's graph is wrong, not the node. Reported as bad input naming the node."""

    exit_code = EXIT_BAD_INPUT
    http_status = 422


class NodeError(PixgraphError, RuntimeError):
    """A node failed while computing, or returned values that break its declaration."""

    exit_code = EXIT_INTERNAL
    http_status = 500

    def __init__(self, node_id: str, type_id: str, message: str):
        super().__init__(f"node {node_id!r} ({type_id}): {message}")
        self.node_id = node_id
        self.type_id = type_id


class NodeInputError(NodeError):
    """A node rejected inputs that do not fit together (``InputError``), or ran out
    of memory on the sizes the graph asks for: bad input."""

    exit_code = EXIT_BAD_INPUT
    http_status = 422


def out_of_memory(what: str = "") -> str:
    """The one message for a ``MemoryError``: what ran out, and what to lower."""
    where = f" {what}" if what else ""
    return (f"ran out of memory{where}: lower the image size (width/height params or the input "
            "files' size), the samples, or the memory cache (--cache-bytes)")


def exit_code(exc: BaseException) -> int:
    """The CLI exit status for ``exc`` (see the table in the module doc)."""
    from .device import DeviceError
    from .events import Cancelled

    if isinstance(exc, PixgraphError):
        return exc.exit_code
    if isinstance(exc, (Cancelled, KeyboardInterrupt)):
        return EXIT_CANCELLED
    if isinstance(exc, MemoryError):
        return EXIT_BAD_INPUT
    if isinstance(exc, DeviceError):
        return EXIT_BAD_INPUT if "matches" in str(exc) else EXIT_INTERNAL
    return EXIT_INTERNAL


def http_status(exc: BaseException) -> int:
    """The HTTP status for ``exc`` (see the table in the module doc)."""
    from .events import Cancelled

    if isinstance(exc, PixgraphError):
        return exc.http_status
    if isinstance(exc, Cancelled):
        return 499
    if isinstance(exc, MemoryError):
        return 507
    return 500


def names_its_input(exc: BaseException) -> bool:
    """True for errors whose one line starts with what was wrong (a file and line, a
    flag, a cache folder); the CLI prefixes the others (a node's, an internal
    failure) with ``error:``."""
    return isinstance(exc, PixgraphError) and not isinstance(exc, (NodeError, InputError))


def message(exc: BaseException) -> str:
    """One line for ``exc``: its text, or for an empty ``MemoryError`` what to lower."""
    if isinstance(exc, MemoryError):
        return out_of_memory() if not str(exc) else f"{out_of_memory()} ({exc})"
    try:
        text = str(exc)
    except Exception:  # noqa: BLE001 - a message that cannot even be formatted
        text = ""
    return one_line(text or type(exc).__name__)
