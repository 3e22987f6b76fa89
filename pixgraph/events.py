"""Run events (progress, cache hits, timings) and cancellation.

Every event is a small frozen dataclass, passed to the ``on_event`` callback of a
run in the order things happen, so a host can drive a progress bar and a log can
answer "why did this run?".
"""
from __future__ import annotations

import dataclasses
import threading


class Cancelled(Exception):
    """The run was cancelled through its ``CancelToken``."""


class CancelToken:
    """Cancel a run from another thread: ``token.cancel()``; nodes notice it at
    their next ``ctx.check_cancelled()``, the engine between nodes."""

    def __init__(self):
        self._event = threading.Event()

    def cancel(self) -> None:
        self._event.set()

    @property
    def cancelled(self) -> bool:
        return self._event.is_set()

    def raise_if_cancelled(self) -> None:
        if self._event.is_set():
            raise Cancelled("run cancelled")


@dataclasses.dataclass(frozen=True)
class RunStarted:
    to_run: int        # nodes that will compute
    cached: int        # nodes served from memory or disk


@dataclasses.dataclass(frozen=True)
class NodeStarted:
    node_id: str
    type_id: str
    reason: str


@dataclasses.dataclass(frozen=True)
class NodeProgress:
    node_id: str
    fraction: float    # 0..1 of this node's work
    message: str


@dataclasses.dataclass(frozen=True)
class NodeLog:
    node_id: str
    message: str


@dataclasses.dataclass(frozen=True)
class NodeFinished:
    node_id: str
    seconds: float     # wall time of compute, including output checks
    stored: str        # "memory", "memory+disk", or "memory only: <why>"


@dataclasses.dataclass(frozen=True)
class NodeCached:
    node_id: str
    where: str         # "memory", "disk" or "bound"


@dataclasses.dataclass(frozen=True)
class RunFinished:
    seconds: float
    ran: int
    cached: int
