"""Running items: plan, skip or run, write, sidecar; and groups of items that share upstream work.

A *group* is a run of items that differ only downstream: the nodes that no
varying override reaches (loading the photo, placing the cutout, its heights,
buffers) have the same cache key in every item of the group. One executor
takes a whole group, runs its items one after the other in one ``Session``, and
keeps the group's shared upstream results in memory for the whole group even
when the memory cache's byte limit would evict them (a 20-megapixel photo's
intermediates are hundreds of MB each).

A row is computed (``compute_item``) and then written (``write_item``: files
through temporaries renamed into place, then sidecars). In a group the writes run
on one writer thread while the next row computes (encoding and compressing a
20-megapixel PNG is most of a second of CPU that needs nothing from the next
row): at most one write is in flight, so at most two rows' outputs are held; a
row is reported when its sidecars are written, in the group's order; a failed
write fails its row only; an interrupted group waits for the write in flight.
"""
from __future__ import annotations

import concurrent.futures
import dataclasses
import os
import socket
import time
from typing import Any, Callable, Sequence

from pixgraph import __version__
from pixgraph.cache import MISS
from pixgraph.events import NodeCached, NodeFinished, NodeStarted
from pixgraph.graph import Graph, GraphError, split_param
from pixgraph.types import nbytes

from .files import content_key, file_sha256, is_done, open_folder, sidecar_path, write_atomic, write_json_atomic
from .items import Item
from .rows import BatchError


@dataclasses.dataclass
class ItemResult:
    index: int
    row: str
    #: "done" (rendered now), "skipped" (already done) or "failed"
    status: str
    outputs: dict[str, str]
    seconds: float = 0.0
    error: str = ""
    worker: str = ""


def worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def failed(item: Item, error: str, seconds: float = 0.0, worker: str = "") -> ItemResult:
    return ItemResult(item.index, item.row, "failed", dict(item.outputs), seconds,
                      error=" ".join(str(error).split()), worker=worker)


# -- groups ----------------------------------------------------------------------------


def downstream(graph: Graph, nodes) -> set[str]:
    """``nodes`` and every node that depends on one of them."""
    users: dict[str, list[str]] = {}
    for nid, inst in graph.nodes.items():
        for ref in inst.inputs.values():
            users.setdefault(ref.node, []).append(nid)
    out, stack = set(), list(nodes)
    while stack:
        n = stack.pop()
        if n in out:
            continue
        out.add(n)
        stack.extend(users.get(n, ()))
    return out


def group_items(graph: Graph, items: Sequence[Item]) -> list[list[Item]]:
    """Items grouped so that a group's items differ only downstream of its fastest-
    varying node: the override with the most distinct values names that node, and
    items with equal values of every override *not* downstream of it (e.g. the same
    cutout file) form one group. Groups keep the items' order; one item per group
    when nothing varies."""
    if len(items) < 2:
        return [list(items)]
    values: dict[str, set[str]] = {}
    for it in items:
        for name, v in it.params.items():
            values.setdefault(name, set()).add(repr(v))
    varying = [n for n, vs in values.items() if len(vs) > 1]
    if not varying:
        return [[it] for it in items]  # identical rows: nothing to share beyond the cache
    fast = max(varying, key=lambda n: len(values[n]))
    below = downstream(graph, [split_param(fast)[0]])
    slow = [n for n in varying if split_param(n)[0] not in below]
    groups: dict[tuple, list[Item]] = {}
    for it in items:
        groups.setdefault(tuple(repr(it.params.get(n)) for n in slow), []).append(it)
    return list(groups.values())


def split_groups(groups: list[list[Item]], workers: int) -> list[list[Item]]:
    """Cut groups into chunks so that ``workers`` processes all get work (each chunk
    computes its upstream once); never more chunks than needed."""
    if len(groups) >= workers:
        return groups
    per = -(-workers // max(1, len(groups)))
    out = []
    for g in groups:
        n = min(per, len(g))
        size = -(-len(g) // n)
        out.extend(g[i:i + size] for i in range(0, len(g), size))
    return out


def shared_nodes(graph: Graph, items: Sequence[Item]) -> set[str]:
    """Nodes whose params no item of the group changes, nor any node upstream of them."""
    if len(items) < 2:
        return set()
    varying = set()
    first = items[0].params
    for it in items[1:]:
        for name in set(first) | set(it.params):
            if repr(first.get(name)) != repr(it.params.get(name)):
                varying.add(split_param(name)[0])
    return set(graph.nodes) - downstream(graph, varying)


class Pins:
    """Upstream results a group shares, held for the whole group: each is taken from
    the session's memory cache the moment its node finishes (or is served from a
    cache), the cache's byte limit is raised by its size while the group runs (so
    pins never crowd out the working set the limit was chosen for), and it is put
    back whenever the LRU evicted it, so the engine finds it in memory for every
    later item of the group. While a shared node computes, the limit is lifted, so
    that a result larger than the whole cache (a 20-megapixel placement under a
    small ``--cache-bytes``) is stored and pinned too. ``clear`` lowers the limit again."""

    #: added to the limit while a shared node computes
    LIFT = 1 << 62

    def __init__(self, session, shared: set[str]):
        self.session = session
        self.shared = shared
        self.values: dict[str, Any] = {}
        self.extra_bytes = 0
        self._keys: dict[str, str] = {}
        self._lifted: set[str] = set()

    def watch(self, plan) -> None:
        """The plan of the item about to run (its node keys)."""
        self._unlift()  # a node of the last item that failed before it finished
        self._keys = {nid: plan.keys[nid] for nid in self.shared if nid in plan.keys}

    def restore(self) -> None:
        memory = self.session.memory
        for key, value in self.values.items():
            if key not in memory:
                memory.put(key, value)

    def on_event(self, event) -> None:
        nid = getattr(event, "node_id", None)
        key = self._keys.get(nid)
        memory = self.session.memory
        if key is not None and key not in self.values:
            if isinstance(event, NodeStarted) and nid not in self._lifted:
                self._lifted.add(nid)
                memory.limit_bytes += self.LIFT
            elif isinstance(event, (NodeFinished, NodeCached)):
                value = memory.get(key)
                if value is not MISS:  # (not stored: a failed store, e.g. a node marked tainted)
                    self.values[key] = value
                    size = nbytes(value)
                    self.extra_bytes += size
                    memory.limit_bytes += size
        if isinstance(event, NodeFinished):
            if nid in self._lifted:
                self._lifted.discard(nid)
                memory.limit_bytes -= self.LIFT
            if self.values:
                self.restore()  # this node's store may have evicted a pinned entry

    def _unlift(self) -> None:
        self.session.memory.limit_bytes -= self.LIFT * len(self._lifted)
        self._lifted.clear()

    def clear(self) -> None:
        self._unlift()
        self.values.clear()
        self.session.memory.limit_bytes -= self.extra_bytes
        self.extra_bytes = 0


def run_group(session, graph: Graph, items: Sequence[Item], force: bool = False,
              on_result: Callable[[ItemResult], None] | None = None, pin: bool = True,
              overlap: bool = True) -> list[ItemResult]:
    """Run a group's items in order in one session, sharing their upstream results;
    with ``overlap`` each row's files are written on a writer thread while the next
    row computes (see the module)."""
    shared = shared_nodes(graph, items) if pin else set()
    pins = Pins(session, shared)
    out = []
    writer = (concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="pixgraph-batch-writer")
              if overlap and len(items) > 1 else None)
    pending = None  # the previous row's write

    def report(r: ItemResult) -> None:
        out.append(r)
        if on_result is not None:
            on_result(r)

    try:
        for item in items:
            pins.restore()
            r = compute_item(session, graph, item, force, pins=pins if shared else None)
            if pending is not None:  # one write in flight at most: wait for the previous row's
                report(pending.result())
                pending = None
            if isinstance(r, ItemResult):  # skipped or failed: nothing to write
                report(r)
            elif writer is None:
                report(write_item(session, r))
            else:
                pending = writer.submit(write_item, session, r)
        if pending is not None:
            report(pending.result())
            pending = None
    finally:
        if writer is not None:  # waits for a write in flight (interrupted: it finishes or removes its temporary)
            writer.shutdown(wait=True)
        pins.clear()
    return out


# -- one item ----------------------------------------------------------------------------


@dataclasses.dataclass
class Rendered:
    """A row computed and not yet written: what ``write_item`` needs."""
    item: Item
    graph: Graph
    plan: Any
    result: Any
    keys: dict[str, str]
    seconds: float
    worker: str


def run_item(session, graph: Graph, item: Item, force: bool = False, pins: Pins | None = None) -> ItemResult:
    """Plan ``item``; skip it when every output is done, else run it and write its
    files and sidecars. Never raises for a failure of the row: it is returned."""
    r = compute_item(session, graph, item, force, pins)
    return r if isinstance(r, ItemResult) else write_item(session, r)


def compute_item(session, graph: Graph, item: Item, force: bool = False,
                 pins: Pins | None = None) -> ItemResult | Rendered:
    """Plan ``item`` and run it: a ``Rendered`` to write, or the row's ``ItemResult``
    when it is skipped (every output done) or failed. Never raises for a failure of the row."""
    t0 = time.perf_counter()
    worker = worker_name()
    try:
        g = session.graph(graph, item.params)
        plan = session.plan(g, list(item.outputs))
        keys = {name: content_key(plan.keys[ref.node], ref.output, item.outputs[name])
                for name, ref in plan.outputs.items()}
        if not force and all(is_done(item.outputs[n], k) for n, k in keys.items()):
            return ItemResult(item.index, item.row, "skipped", dict(item.outputs), time.perf_counter() - t0,
                              worker=worker)
        _check_outputs(session, g, item)
        if pins is not None:
            pins.watch(plan)
        res = session.run_plan(plan, on_event=pins.on_event if pins is not None else None)
        return Rendered(item, g, plan, res, keys, time.perf_counter() - t0, worker)
    except Exception as e:  # one row's failure is reported, the batch goes on
        return failed(item, _message(e), time.perf_counter() - t0, worker)


def write_item(session, rendered: Rendered) -> ItemResult:
    """Write a computed row's files (temporary + rename) and then their sidecars;
    the row's seconds are its compute plus its write. Never raises for a failure of the row."""
    t0 = time.perf_counter()
    item, g = rendered.item, rendered.graph
    try:
        folders = {}
        try:  # each output's folder held open from its image to its sidecar (no symlink swapped in between)
            digests = {}
            for name, path in item.outputs.items():
                folders[name] = open_folder(path)[0]
                digests[name] = _write_output(session, g, name, rendered.result.outputs[name], path, folders[name])
            seconds = rendered.seconds + time.perf_counter() - t0
            for name, path in item.outputs.items():
                write_json_atomic(sidecar_path(path), sidecar(session, g, rendered.plan, rendered.result, item,
                                                              name, rendered.keys[name], digests[name], seconds),
                                  folders[name])
        finally:
            for folder in folders.values():
                folder.close()
        return ItemResult(item.index, item.row, "done", dict(item.outputs), seconds, worker=rendered.worker)
    except Exception as e:
        return failed(item, _message(e), rendered.seconds + time.perf_counter() - t0, rendered.worker)


def _message(e: Exception) -> str:
    return str(e) if isinstance(e, (GraphError, BatchError)) else f"{type(e).__name__}: {e}"


def _check_outputs(session, graph: Graph, item: Item) -> None:
    """Never overwrite a file this row reads, never a path with control characters."""
    from pixgraph.paths import PathError

    try:
        session.check_output_paths(graph, item.outputs)
    except PathError as e:
        raise BatchError(e.message) from None


def _write_output(session, graph: Graph, name: str, value, path: str, folder) -> str:
    """Write like ``pixgraph run -o`` (the port type's encoding), through a
    temporary file renamed into place; returns the sha256 of the bytes written."""
    def write(tmp: str) -> None:
        try:
            session.write_output(graph, name, value, tmp)
        except ValueError as e:  # name the user's path, not the temporary
            raise BatchError(str(e).replace(tmp, path)) from None

    return write_atomic(path, write, folder)


def graph_sha256(graph: Graph) -> str | None:
    if graph.file is None:
        return None
    try:
        return file_sha256(graph.file)
    except OSError:
        return None


def sidecar(session, graph, plan, res, item: Item, name: str, key: str, digest: str,
            seconds: float) -> dict[str, Any]:
    """The provenance of one output file (``PATH.json``)."""
    ref = plan.outputs[name]
    methods = {}
    for s in plan.steps:
        p = plan.params.get(s.node_id, {})
        chosen = {k: p[k] for k in ("method", "kind", "mode", "material") if k in p}
        methods[s.node_id] = {"type": s.type_id, **chosen}
    device = None
    if session.device_opened:
        dev = session.device
        device = str(getattr(dev, "name", None) or dev)
    return {
        "pixgraph": __version__,
        "graph": os.path.abspath(graph.file) if graph.file else None,
        "graph_sha256": graph_sha256(graph),
        "row": item.row,
        "source": item.source,
        "params": dict(item.params),
        "output": name,
        "ref": f"{ref.node}.{ref.output}",
        "path": item.outputs[name],
        "node_key": plan.keys[ref.node],
        "content_key": key,
        "file_sha256": digest,
        "methods": methods,
        "ran": list(res.ran),
        "cached": list(res.cached),
        "device": device,
        "seconds": round(seconds, 6),
        "host": socket.gethostname(),
        "pid": os.getpid(),
        "time": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
    }
