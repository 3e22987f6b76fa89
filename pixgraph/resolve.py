"""Resolving a node's params for a plan: defaults and coercion, the path policy,
the files' content hashes that go into cache keys, and the overwrite check (a run
may not write over a file it reads). ``Engine.plan`` and ``Engine.check`` use it.
"""
from __future__ import annotations

import os
from typing import Callable, Mapping

from .graph import Graph, GraphError
from .node import NodeSpec
from .paths import PathError, PathPolicy, WritePath
from .registry import Registry


def checked_path(graph: Graph, policy: PathPolicy, nid: str, p, raw) -> str:
    """A path param checked against the policy and made absolute; a ``PathError``
    naming the node, the param and the graph file's line."""
    field = f"params.{p.name}"
    try:
        resolved = graph.resolve_path(os.fspath(raw))
        checked = (policy.check_write if p.writes else policy.check_read)(resolved, node=nid, param=p.name)
    except PathError as e:
        located = graph.error(e.message, node=nid, field=field)
        raise PathError(e.message, file=located.file, line=located.line, node=nid, field=field) from None
    except ValueError as e:  # e.g. embedded NUL in a home-folder lookup
        located = graph.error(f"bad path: {e}"[:200], node=nid, field=field)
        raise PathError(located.message, file=located.file, line=located.line, node=nid, field=field) from None
    # the node gets the path as the graph names it (made absolute), so its messages
    # name the user's path; the check above resolved every symlink in it, and a
    # written path carries the folder it checked (writers never follow a symlink)
    return WritePath(resolved, os.fspath(checked)) if p.writes else resolved

def check_overwrites(registry: Registry, graph: Graph, params, order, bind) -> None:
    """A node may not write over a file that this run reads (or the graph file)."""
    reads = {os.path.realpath(graph.file): "the graph file"} if graph.file else {}
    writes = []
    for nid in order:
        if nid in bind:
            continue
        spec = registry.get(graph.nodes[nid].type)
        for p in spec.params:
            if p.kind == "path" and params[nid].get(p.name) is not None:
                real = os.path.realpath(params[nid][p.name])
                if p.writes:
                    writes.append((nid, p.name, real))
                else:
                    reads.setdefault(real, f"node {nid!r} param {p.name!r}")
    for nid, pname, path in writes:
        if path in reads:
            raise located_error(graph, f"would write over {reads[path]}, read by this run ({path})",
                                nid, f"params.{pname}")

def located_error(graph: Graph, message: str, nid: str, field: str) -> PathError:
    e = graph.error(message, node=nid, field=field)
    return PathError(e.message, file=e.file, line=e.line, node=nid, field=field)

def resolve_params(graph: Graph, nid: str, spec: NodeSpec, values, policy: PathPolicy | None,
                   hash_file: Callable[[str], str], max_file_bytes: int,
                   read_paths: bool = True) -> tuple[dict, dict]:
    """A node's params as compute gets them (defaults, coercion, absolute checked
    paths) and the part of them its cache key holds (``cache=True`` params, the
    sha256 of each file it reads, the path of each file it writes)."""
    params = spec.coerce_params(values)
    relevant = {}
    for p in spec.params:
        if p.kind == "path" and not read_paths:
            continue  # a bound host input reads no file
        if p.kind == "path":
            params[p.name] = checked_path(graph, policy, nid, p, params[p.name])
            if p.writes:
                relevant[p.name] = params[p.name]
            else:
                try:
                    size = os.path.getsize(params[p.name])
                    if size > max_file_bytes:
                        raise graph.error(f"file is {size} bytes, more than the limit of {max_file_bytes} "
                                          "(PIXGRAPH_MAX_FILE_BYTES)", node=nid, field=f"params.{p.name}")
                    relevant[p.name] = {"file_sha256": hash_file(params[p.name])}
                except OSError as e:
                    raise graph.error(f"cannot read {params[p.name]}: {e.strerror}", node=nid,
                                      field=f"params.{p.name}") from None
        elif p.cache:
            v = params[p.name]
            relevant[p.name] = list(v) if isinstance(v, tuple) else v
    return params, relevant


def check_scale(scale) -> float:
    try:
        scale = float(scale)
    except (TypeError, ValueError):
        raise GraphError(f"scale must be a number in (0, 1], got {scale!r}") from None
    if not 0.0 < scale <= 1.0:
        raise GraphError(f"scale must be in (0, 1] (1 = full size), got {scale!r}")
    return scale


def scale_params(spec: NodeSpec, params: dict, relevant: dict, scale: float) -> None:
    """A scaled run (``Engine.plan``): params declared in pixels (``unit="px"``)
    times ``scale``, in ``params`` (what compute gets) and ``relevant`` (the key);
    a node with ``uses_scale = True`` gets ``@scale`` in its key."""
    def one(p, v):
        v = v * scale
        if p.kind == "int":
            v = int(round(v))
        if p.min is not None:
            v = max(v, p.min)
        if p.max is not None:
            v = min(v, p.max)
        return v
    for p in spec.params:
        if p.unit != "px" or p.kind not in ("int", "float", "floats") or params.get(p.name) is None:
            continue
        v = params[p.name]
        params[p.name] = tuple(one(p, x) for x in v) if p.kind == "floats" else one(p, v)
        if p.name in relevant:
            relevant[p.name] = list(params[p.name]) if p.kind == "floats" else params[p.name]
    if spec.cls.uses_scale:  # declared on node.Node
        relevant["@scale"] = scale



class PlanMemo:
    """What ``Engine.plan`` worked out for a node (checked params, key parts, key),
    by what it depends on when the node reads no file: its class, params as set,
    input keys and the working scale (the code hash is fixed per process). A warm
    plan of an edited graph then re-checks and re-hashes only the nodes that changed."""

    #: entries kept (the memo is emptied whole when full)
    size = 20000

    def __init__(self):
        self._memo: dict[tuple, tuple] = {}

    @staticmethod
    def key(spec, inst, inputs: Mapping[str, str], scale: float):
        """None for a node with path params (a file can change between plans) or
        with unhashable param values."""
        if spec.has_paths:
            return None
        try:
            k = (spec.cls, spec.type_id, spec.version, tuple(inst.params.items()), tuple(inputs.items()), scale)
            hash(k)
        except TypeError:
            return None
        return k

    def get(self, key):
        hit = self._memo.get(key) if key is not None else None
        return None if hit is None else (dict(hit[0]), hit[1], hit[2])

    def put(self, key, params: dict, parts, node_key: str) -> None:
        if key is None:
            return
        if len(self._memo) >= self.size:
            self._memo.clear()
        self._memo[key] = (dict(params), parts, node_key)
