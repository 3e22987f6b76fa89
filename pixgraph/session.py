"""The embedding API: the one object a host application holds.

    from pixgraph.session import Session
    s = Session(cache_bytes=2**30)
    out = s.run("graphs/shadow.yaml", params={"blur.sigma": 4},
                bind={"cutout": rgba_float32}, outputs=["final"])

A ``Session`` owns a registry (discovered from entry points unless given), a
byte-bounded memory cache, an optional disk cache, and an OpenCL device that is
opened the first time a node asks for one. Repeated runs reuse cached results;
``plan``/``explain`` say what a run would do, and why, without running it.
"""
from __future__ import annotations

import os
from typing import Any, Callable, Mapping

from . import fileio
from .cache import DiskCache, MemoryCache
from .engine import Engine, Plan, RunResult
from .events import CancelToken
from .graph import Graph, GraphBuilder, GraphError, Ref, split_param
from .options import env_int
from .paths import PathError, PathPolicy, bad_characters, quote
from .registry import Registry

#: defaults, each overridable by a Session argument or an environment variable
DEFAULT_CACHE_BYTES = 2 << 30          # PIXGRAPH_CACHE_BYTES
DEFAULT_DISK_CACHE_BYTES = 20 << 30    # PIXGRAPH_DISK_CACHE_BYTES


def env_bytes(name: str, default: int) -> int:
    value = env_int(name, default, "a number of bytes")
    if value < 0:
        raise ValueError(f"{name} must be >= 0, got {os.environ[name][:40]!r}")
    return value


class Session:
    """Registry + caches + device; runs graphs from files, text or ``Graph`` values.

    device: ``None`` (``PIXGRAPH_DEVICE`` or the default choice), a spec string
        (``"0:0"``, ``"cpu"``, a name substring), or a ``pixgraph.device.Device``
        (e.g. ``Device.from_cl(host_context, host_queue)``). Opened lazily.
    cache_bytes: memory cache limit in bytes (default ``PIXGRAPH_CACHE_BYTES`` or 2 GiB).
    disk_cache: folder of a persistent cache, or ``None`` for none (the CLI
        passes ``--disk-cache``, ``PIXGRAPH_DISK_CACHE`` or ``~/.cache/pixgraph``).
    disk_cache_bytes: disk cache limit (default ``PIXGRAPH_DISK_CACHE_BYTES`` or 20 GiB).
    registry: node types; default ``Registry.discover()``.
    allow_paths: folders that path params may read and write besides the graph
        file's folder (a built graph's ``base_dir``, by default the current
        directory); ``PIXGRAPH_ALLOW_PATHS`` adds more unless ``strict_paths``.
    strict_paths: only the graph's folder and ``allow_paths`` (the HTTP server).
        See ``pixgraph.paths`` and docs/security.md.
    """

    def __init__(self, device=None, cache_bytes: int | None = None, disk_cache: str | os.PathLike | None = None,
                 registry: Registry | None = None, disk_cache_bytes: int | None = None,
                 allow_paths=(), strict_paths: bool = False, workers: int | None = None):
        self.registry = registry if registry is not None else Registry.discover()
        if cache_bytes is None:
            cache_bytes = env_bytes("PIXGRAPH_CACHE_BYTES", DEFAULT_CACHE_BYTES)
        if disk_cache_bytes is None:
            disk_cache_bytes = env_bytes("PIXGRAPH_DISK_CACHE_BYTES", DEFAULT_DISK_CACHE_BYTES)
        self.memory = MemoryCache(cache_bytes)
        self.disk = DiskCache(disk_cache, disk_cache_bytes) if disk_cache is not None else None
        self._device_arg = device
        self._device = None
        self.paths = PathPolicy(allow_paths, strict=strict_paths)
        self.engine = Engine(self.registry, self.memory, self.disk, self._get_device, paths=self.paths)
        if workers is not None:  # independent branches at once (default PIXGRAPH_WORKERS, else 1)
            self.engine.workers = max(1, int(workers))
        self.last_run: RunResult | None = None

    @property
    def device(self):
        """The session's ``Device``, opened on first use."""
        return self._get_device()

    def _get_device(self):
        if self._device is None:
            from .device import Device

            arg = self._device_arg
            self._device = arg if isinstance(arg, Device) else Device.open(arg)
        return self._device

    @property
    def device_opened(self) -> bool:
        return self._device is not None

    # -- graphs -----------------------------------------------------------------

    def load(self, path: str | os.PathLike) -> Graph:
        return fileio.load(path, self.registry)

    def builder(self, base_dir: str | None = None) -> GraphBuilder:
        return GraphBuilder(self.registry, base_dir=base_dir)

    def graph(self, graph_or_path: Graph | str | os.PathLike, params: Mapping[str, Any] | None = None) -> Graph:
        """A validated graph from a file or value, with param overrides applied.

        ``params`` is ``{"node.param": value}`` or ``{"node": {"param": value}}``;
        values are validated like file params.
        """
        graph = graph_or_path if isinstance(graph_or_path, Graph) else self.load(graph_or_path)
        if not params:
            return graph
        b = GraphBuilder.from_graph(graph, self.registry)
        overridden = set()
        for name, value in params.items():
            if isinstance(value, Mapping) and "." not in name:
                node_id, values = name, dict(value)
            else:
                node_id, pname = split_param(name, what="param override")
                values = {pname: value}
            if node_id not in graph.nodes:
                raise GraphError("param override for a node that is not in the graph", file=graph.file, node=node_id)
            b.set(node_id, **values)
            overridden.update((node_id, f"params.{k}") for k in values)
        try:
            return b.build()
        except GraphError as e:
            if (e.node, e.field) in overridden:  # the bad value is the override, not the file's line
                raise GraphError(f"{e.message} (set by a param override)", file=graph.file,
                                 node=e.node, field=e.field) from None
            raise

    def allow_files(self, files) -> None:
        """Allow these exact files too (paths a person typed, not ones from a graph file)."""
        self.paths = self.paths.with_files(files)
        self.engine.paths = self.paths

    def check_paths(self, graph_or_path, params=None) -> Graph:
        """The graph, after checking every path param against the path policy
        (raises ``paths.PathError``); ``plan`` and ``run`` check the nodes they need."""
        graph = self.graph(graph_or_path, params)
        self.engine.check_paths(graph)
        return graph

    # -- plan and run -----------------------------------------------------------

    def plan(self, graph_or_path, outputs=None, params=None, bind=None, scale: float = 1.0) -> Plan:
        return self.engine.plan(self.graph(graph_or_path, params), outputs, bind, scale=scale)

    def check(self, graph_or_path, outputs=None, params=None, notes: list[str] | None = None) -> dict:
        """Check before running, from file headers only (``Engine.check``): sizes that
        do not fit, cutouts without alpha, placements off the canvas... Raises the
        first problem as a ``GraphError`` naming the node and the files; warnings
        (e.g. a horizon that does not fit the placement) are appended to ``notes``."""
        return self.engine.check(self.graph(graph_or_path, params), outputs, notes=notes)

    def explain(self, graph_or_path, outputs=None, params=None, bind=None) -> str:
        return self.plan(graph_or_path, outputs, params, bind).table()

    def run(self, graph_or_path, outputs=None, params=None, bind: Mapping[str, Any] | None = None,
            cancel: CancelToken | None = None, on_event: Callable[[Any], None] | None = None,
            scale: float = 1.0) -> RunResult:
        """Run and return a ``RunResult``: a mapping ``{output name: value}`` that also
        says what ran (``ran``, ``cached``, ``seconds``, ``timings``, ``logs``, ``said``).

        outputs: names from the graph's ``outputs`` or ``"node.output"`` refs;
            default all of the graph's outputs.
        bind: ``{node_id: array}``: a host array for that node (keyed by its bytes,
            shape and dtype); its inputs are not run. A host input node (one with a
            ``bind`` method: ``pixgraph.InputImage``, ``InputMask``,
            ``InputPixelHeight``, ``LoadImage``...) turns the array into all its
            outputs; any other node's first output is replaced by the array.
        cancel: a ``CancelToken``; cancelling raises ``events.Cancelled``.
        on_event: called with each ``pixgraph.events`` event.
        scale: working resolution in (0, 1]: loaders read images this many times
            their size and params in pixels are scaled with them (``Engine.plan``),
            e.g. a screen-sized preview of a 20 MP photo; 1 (default) is full size.
        """
        graph = self.graph(graph_or_path, params)
        for nid, value in (bind or {}).items():
            if nid not in graph.nodes:
                raise GraphError("cannot bind: no such node in the graph", file=graph.file, node=nid)
            spec = self.registry.get(graph.nodes[nid].type)
            if "bind" in spec.hooks:
                continue  # a host input checks the array itself, in the plan
            port = spec.outputs[0]
            try:
                port.type.validate(value)
            except TypeError as e:
                raise GraphError(f"bound value does not fit output {port.name!r}: {e}", node=nid) from None
        return self.run_plan(self.engine.plan(graph, outputs, bind, scale=scale), cancel, on_event)

    def run_plan(self, plan: Plan, cancel: CancelToken | None = None,
                 on_event: Callable[[Any], None] | None = None) -> RunResult:
        """Run a plan made by ``plan`` (what a shell does when it wants to look at
        the plan first, e.g. to skip work that is already done)."""
        self.last_run = self.engine.run(plan, cancel, on_event)
        return self.last_run

    # -- outputs and files ------------------------------------------------------

    def output_type(self, graph: Graph, name: str):
        """The declared port type of a graph output name or a ``"node.output"`` ref."""
        ref = graph.outputs.get(name) or Ref.parse(name)
        if ref.node not in graph.nodes:
            raise GraphError(f"no output {name!r}: no node {ref.node!r} in the graph", file=graph.file)
        port = self.registry.get(graph.nodes[ref.node].type).output(ref.output)
        if port is None:
            raise GraphError(f"no output {name!r}: node {ref.node!r} has no output {ref.output!r}",
                             file=graph.file, node=ref.node)
        return port.type

    def write_output(self, graph: Graph, name: str, value: Any, path: str | os.PathLike) -> str:
        """Write one output value to ``path`` the way its port type writes files (an
        image as colour, a matte or a pixel height as data: the port type's ``write``).
        Creates the folder; returns the path written. Raises ``ValueError`` (naming
        the output and the path) when the value cannot be written there."""
        port_type = self.output_type(graph, name)
        path = os.fspath(path)
        write = getattr(port_type, "write", None)
        if write is None:
            raise ValueError(f"output {name!r} ({port_type.type_name()}) cannot be written to a file")
        os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
        try:
            return write(path, value) or path
        except (ValueError, TypeError, OSError) as e:
            raise ValueError(f"output {name!r} -> {path}: {e}") from None

    def reads(self, graph: Graph) -> dict[str, str]:
        """Every file a run of this graph may read (its real path) -> who reads it."""
        reads = {os.path.realpath(graph.file): "the graph file"} if graph.file else {}
        for nid, inst in graph.nodes.items():
            spec = self.registry.get(inst.type)
            for p in spec.params:
                if p.kind == "path" and not p.writes and inst.params.get(p.name) is not None:
                    real = os.path.realpath(graph.resolve_path(os.fspath(inst.params[p.name])))
                    reads.setdefault(real, f"node {nid!r} param {p.name!r}")
        return reads

    def check_output_paths(self, graph: Graph, targets: Mapping[str, str | os.PathLike]) -> None:
        """Output files a person named (``-o``, a batch template, a host's path) may be
        anywhere, but never hold control characters and never overwrite a file this
        graph reads. Raises ``paths.PathError`` naming the output."""
        reads = self.reads(graph)
        for name, path in targets.items():
            path = os.fspath(path)
            why = bad_characters(path)
            if why:
                raise PathError(f"output {name}: path {quote(path)} {why}")
            real = os.path.realpath(path)
            if real in reads:
                raise PathError(f"output {name}: {quote(path)} would write over {reads[real]}, read by this run")

    def policy_for(self, graph: Graph) -> PathPolicy:
        """The path policy that applies to one graph (the session's folders plus the graph's)."""
        return self.engine.policy_for(graph)

    @property
    def device_spec(self):
        """The device this session was asked for (a spec string, a ``Device`` or None),
        e.g. for a shell that opens the same device in another process."""
        return self._device_arg

    def cache_stats(self) -> dict:
        return {"memory": self.memory.stats(), "disk": self.disk.stats() if self.disk else None}


_env_bytes = env_bytes  # the former name
