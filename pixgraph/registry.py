"""The node registry: which node types exist, and where each came from.

A ``Registry`` is a plain object (one per session; there is no process-global
registry). ``Registry.discover()`` loads every entry point of the group
``pixgraph.nodes``. An entry point's value is either

- a callable returning node classes (``pixgraph_nodes:nodes``). It may accept a
  keyword ``report(source, exception)``: a pack with many modules then reports a
  module that fails to import and returns the rest; or
- a module, whose node classes (those defined in it) are collected.

Loading never stops at the first broken plugin: a plugin that fails to import and
a node type id registered twice are recorded in ``registry.errors`` (shown by
``pixgraph nodes --errors``) and every other node stays usable. A duplicate id
is an error naming both sources; the first one registered keeps the id (the
built-in pack loads first, then plugins by entry-point name).
"""
from __future__ import annotations

import dataclasses
import importlib.metadata
import inspect
import traceback
import types
from typing import Callable, Iterable

from .node import NodeSpec, is_node_class
from .types import BUILTIN, PortType

ENTRY_POINT_GROUP = "pixgraph.nodes"


@dataclasses.dataclass(frozen=True)
class PluginError:
    """One problem met while loading plugins: ``source`` names where (entry point,
    module or class), ``message`` says what, in one line."""

    source: str
    message: str
    detail: str = ""  # the traceback, for --debug

    def __str__(self) -> str:
        return f"{self.source}: {self.message}"


class UnknownNodeType(KeyError):
    def __init__(self, type_id: str, known: Iterable[str]):
        super().__init__(type_id)
        self.type_id = type_id
        self.known = tuple(known)

    def __str__(self) -> str:
        return f"unknown node type {self.type_id!r}"


def _entry_points(group: str):
    return importlib.metadata.entry_points(group=group)


class Registry:
    """Node types by namespaced id (``"pixgraph.GaussianBlur"``), with their sources.

    ``Registry()`` is empty; ``Registry.discover()`` fills one from entry points;
    ``registry.add(cls, source=...)`` registers node classes directly (tests, hosts).
    """

    def __init__(self):
        self._specs: dict[str, NodeSpec] = {}
        self._sources: dict[str, str] = {}
        self.errors: list[PluginError] = []

    @classmethod
    def discover(cls, group: str = ENTRY_POINT_GROUP,
                 entry_points: Callable[[str], Iterable] = _entry_points) -> "Registry":
        """A registry with every node of every installed plugin.

        ``entry_points(group)`` returns objects with ``.name``, ``.value`` and
        ``.load()`` (``importlib.metadata`` by default; tests inject their own).
        """
        reg = cls()
        # built-in nodes first, so a plugin can never take over a built-in id
        for ep in sorted(entry_points(group), key=lambda e: (not e.value.startswith("pixgraph_nodes"),
                                                             e.name, e.value)):
            reg.load_entry_point(ep)
        return reg

    def load_entry_point(self, ep) -> None:
        source = f"entry point {ep.name!r} ({ep.value})"
        try:
            obj = ep.load()
        except Exception as exc:  # a broken plugin must not take the others down
            self._error(source, exc)
            return
        self.load_plugin(obj, source)

    def load_plugin(self, obj, source: str) -> None:
        """Register the node classes of ``obj``: a module or a callable (see module doc)."""
        if isinstance(obj, types.ModuleType):
            classes = [v for v in vars(obj).values() if is_node_class(v) and v.__module__ == obj.__name__]
        elif callable(obj):
            try:
                if "report" in inspect.signature(obj).parameters:
                    classes = list(obj(report=lambda where, exc: self._error(f"{source}: {where}", exc)))
                else:
                    classes = list(obj())
            except Exception as exc:
                self._error(source, exc)
                return
        else:
            self.errors.append(PluginError(source, f"is a {type(obj).__name__}, expected a module or a callable"))
            return
        for c in classes:
            if not is_node_class(c):
                self.errors.append(PluginError(source, f"returned {c!r}, which is not a @node class"))
                continue
            self.add(c, source=source)

    def _error(self, source: str, exc: BaseException) -> None:
        msg = f"failed to load: {type(exc).__name__}: {exc}".splitlines()[0]
        self.errors.append(PluginError(source, msg, "".join(traceback.format_exception(exc))))

    def add(self, cls: type, source: str | None = None) -> bool:
        """Register one node class. A duplicate id is recorded as an error naming
        both sources and the first registration is kept. Returns True if added."""
        if not is_node_class(cls):
            raise TypeError(f"{cls!r} is not a node class (decorate it with @node)")
        spec: NodeSpec = cls.spec
        where = f"{source}: {spec.source}" if source else spec.source
        if spec.type_id in self._specs:
            if self._specs[spec.type_id].cls is cls:
                return False
            self.errors.append(PluginError(
                where, f"duplicate node type {spec.type_id!r}: already registered by "
                       f"{self._sources[spec.type_id]}; this one is ignored"))
            return False
        self._specs[spec.type_id] = spec
        self._sources[spec.type_id] = where
        return True

    def get(self, type_id: str) -> NodeSpec:
        """The spec of a node type; raises ``UnknownNodeType``."""
        try:
            return self._specs[type_id]
        except KeyError:
            raise UnknownNodeType(type_id, self._specs) from None

    def source(self, type_id: str) -> str:
        return self._sources[type_id]

    def __contains__(self, type_id: str) -> bool:
        return type_id in self._specs

    def __iter__(self):
        return iter(sorted(self._specs))

    def __len__(self) -> int:
        return len(self._specs)

    def specs(self) -> list[NodeSpec]:
        """Every registered spec, sorted by type id."""
        return [self._specs[k] for k in sorted(self._specs)]

    def port_types(self) -> dict[str, type]:
        """Every port type by name: the engine's own (``Any``, ``Scalar``) and those
        of the registered nodes' ports, for the file format, schema and references.
        Two packs' types of one name: the first registered keeps it."""
        out = dict(BUILTIN)
        for spec in self.specs():
            for p in spec.inputs + spec.outputs:
                for t in p.type.__mro__:  # a Mask brings the Image it may feed
                    if isinstance(t, type) and issubclass(t, PortType) and t is not PortType:
                        out.setdefault(t.type_name(), t)
        return out

    def suggest(self, type_id: str) -> str | None:
        """The closest registered id, for 'did you mean' hints."""
        import difflib

        hit = difflib.get_close_matches(type_id, list(self._specs), n=1)
        return hit[0] if hit else None
