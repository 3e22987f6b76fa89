"""Running the nodes of a run in dependency order, one at a time or concurrently.

``Engine.run`` first resolves what it can from the caches, then hands the nodes
that must compute to ``execute`` with their dependencies among themselves.
``workers == 1`` (the default) runs them in the given order on the calling
thread. With more workers, independent branches run on a thread pool: numpy,
OpenCV-style C loops and torch release the GIL, so two branches' host work can
overlap. The OpenCL device is shared by the whole session, so a node that opens
``ctx.device`` holds the session's device lock until its compute ends
(``DeviceGate``): device nodes run one at a time, host nodes beside them.
Whether it pays depends on the machine: benchmarks/engine_concurrency.py.
"""
from __future__ import annotations

import concurrent.futures as cf
import threading
from typing import Any, Callable, Iterable, Mapping

from . import events as E


def execute(order: list[str], deps: Mapping[str, Iterable[str]], work: Callable[[str], None],
            workers: int = 1, cancel: E.CancelToken | None = None) -> None:
    """Call ``work(node)`` for every node of ``order`` after ``work`` returned for
    each of its ``deps`` (nodes outside ``order`` count as done). ``order`` must
    list inputs before the nodes that use them. The first exception stops new
    work, waits for the nodes already running, and is raised."""
    if workers <= 1 or len(order) <= 1:
        for nid in order:
            if cancel is not None:
                cancel.raise_if_cancelled()
            work(nid)
        return
    todo = set(order)
    waiting = {n: {d for d in deps.get(n, ()) if d in todo} for n in order}
    users: dict[str, list[str]] = {n: [] for n in order}
    for n, ds in waiting.items():
        for d in ds:
            users[d].append(n)
    rank = {n: i for i, n in enumerate(order)}
    ready = [n for n in order if not waiting[n]]
    error: BaseException | None = None
    with cf.ThreadPoolExecutor(max_workers=workers, thread_name_prefix="pixgraph-node") as pool:
        running: dict[cf.Future, str] = {}
        while ready or running:
            while ready and error is None and len(running) < workers:
                if cancel is not None and cancel.cancelled:
                    error = E.Cancelled("run cancelled")
                    break
                nid = ready.pop(0)
                running[pool.submit(work, nid)] = nid
            if not running:
                break
            done, _ = cf.wait(running, return_when=cf.FIRST_COMPLETED)
            for fut in done:
                nid = running.pop(fut)
                exc = fut.exception()
                if exc is not None:
                    error = error or exc
                    continue
                for u in users[nid]:
                    waiting[u].discard(nid)
                    if not waiting[u]:
                        ready.append(u)
                ready.sort(key=rank.__getitem__)
            if error is not None:
                ready.clear()
    if error is not None:
        raise error


class DeviceGate:
    """The session's device, handed to one node at a time when nodes run
    concurrently: ``opener()`` takes the lock on a node's first ``ctx.device`` and
    keeps it until ``release()`` at the end of that node's compute."""

    def __init__(self, device: Callable[[], Any]):
        self._device = device
        self._lock = threading.Lock()
        self._held = threading.local()

    def opener(self) -> Callable[[], Any]:
        def open_device():
            if not getattr(self._held, "on", False):
                self._lock.acquire()
                self._held.on = True
            return self._device()
        return open_device

    def release(self) -> None:
        if getattr(self._held, "on", False):
            self._held.on = False
            self._lock.release()
