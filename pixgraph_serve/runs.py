"""Runs by id, their encoded outputs, and the renders of each page.

``POST /api/run`` records what it ran (the immutable ``Graph``, the mode and the
output names) under a new run id; ``GET /api/outputs/NAME.png?run=ID`` asks the
session for that graph's output again (the memory cache answers, or it is
recomputed: the engine is deterministic) and so returns that run's image even
when another client has edited the graph since. A record holds no pixels; the
newest ``max_runs`` are kept, and at most ``max_bytes`` of graphs (each graph counted
once however many runs share it, by ``history.graph_bytes``: a graph of 8,000 nodes
holds 13 MiB loaded, ``benchmarks/serve_bounds_bench.py``, so 256 runs of edits of it
were gigabytes); the newest is kept whatever its size.

Encoded files are kept in a small cache bounded in bytes, keyed by run id, output,
format and scale, and made once: requests for the same file wait for the first one
to encode it (under the run lock) and then share the same bytes.
"""
from __future__ import annotations

import collections
import dataclasses
import secrets
import threading

from pixgraph.events import CancelToken
from pixgraph.graph import Graph

from .errors import ServeError
from .history import graph_bytes


@dataclasses.dataclass(frozen=True)
class Run:
    id: str
    graph: Graph            # the graph as it was run (the edited graph, not its preview)
    mode: str               # "final" or "preview"
    outputs: tuple[str, ...]


class Runs:
    """The newest ``max_runs`` run records, by id, holding at most ``max_bytes`` of
    distinct graphs (the newest kept whatever its size)."""

    def __init__(self, max_runs: int = 256, max_bytes: int = 64 << 20):
        self.max_runs = max_runs
        self.max_bytes = max_bytes
        self._runs: collections.OrderedDict[str, Run] = collections.OrderedDict()
        #: id(graph) -> [runs holding it, its estimated bytes]
        self._graphs: dict[int, list] = {}
        self.bytes = 0          # estimated bytes of the distinct graphs held [bytes]
        self._lock = threading.Lock()

    def add(self, graph: Graph, mode: str, outputs) -> Run:
        run = Run(secrets.token_hex(8), graph, mode, tuple(outputs))
        with self._lock:
            self._runs[run.id] = run
            held = self._graphs.get(id(graph))      # the key lives while a run holds the graph
            if held is None:
                held = self._graphs[id(graph)] = [0, graph_bytes(graph)]     # 0.05-0.13 s at 8,000 nodes
                self.bytes += held[1]
            held[0] += 1
            while len(self._runs) > 1 and (len(self._runs) > self.max_runs or self.bytes > self.max_bytes):
                _, old = self._runs.popitem(last=False)
                entry = self._graphs[id(old.graph)]
                entry[0] -= 1
                if entry[0] == 0:
                    self.bytes -= entry[1]
                    del self._graphs[id(old.graph)]
        return run

    def get(self, run_id: str) -> Run:
        with self._lock:
            run = self._runs.get(run_id)
        if run is None:
            raise ServeError(404, f"no run {run_id!r} (the server keeps the newest {self.max_runs} runs)",
                             field="run")
        return run


class Encoded:
    """Encoded output files, least recently used first out, at most ``max_bytes`` in all
    (the newest file is kept even when it alone is larger)."""

    def __init__(self, max_bytes: int = 64 << 20):
        self.max_bytes = max_bytes
        self._files: collections.OrderedDict[tuple, bytes] = collections.OrderedDict()
        self._size = 0
        self.encodes = 0      # files encoded so far (each miss)

    def get(self, key: tuple) -> bytes | None:
        data = self._files.get(key)
        if data is not None:
            self._files.move_to_end(key)
        return data

    def put(self, key: tuple, data: bytes) -> bytes:
        self.encodes += 1
        old = self._files.pop(key, None)
        self._size -= len(old) if old is not None else 0
        self._files[key] = data
        self._size += len(data)
        while self._size > self.max_bytes and len(self._files) > 1:
            _, dropped = self._files.popitem(last=False)
            self._size -= len(dropped)
        return data


class Renders:
    """Per-client newest sequence number and the token of its running render: a render
    that a newer one of the same client superseded is dropped before it starts and
    cancelled while it runs, so drags never queue work. At most ``max_clients`` clients
    are remembered (the most recently seen; one with a render running is never
    forgotten), so requests under ever new client ids cannot grow it without bound; a
    forgotten client's next render simply counts as its first."""

    def __init__(self, max_clients: int = 256):
        self.latest: collections.OrderedDict[str, int] = collections.OrderedDict()
        self.tokens: dict[str, CancelToken] = {}
        self.dropped = 0
        self.max_clients = max_clients

    def claim(self, client: str, seq: int) -> bool:
        """Record ``seq`` as the client's newest; False when a newer one came first."""
        if seq <= self.latest.get(client, -1):
            return False
        self.latest[client] = seq
        self.latest.move_to_end(client)
        if len(self.latest) > self.max_clients:
            for old in [c for c in self.latest if c not in self.tokens][:len(self.latest) - self.max_clients]:
                del self.latest[old]
        token = self.tokens.get(client)
        if token is not None:
            token.cancel()  # its result would be stale: stop it
        return True

    def current(self, client: str, seq: int) -> bool:
        return self.latest.get(client) == seq
