"""The graph file: YAML load and canonical dump, migrations, and JSON Schema.

Format (version 1)::

    pixgraph: 1
    nodes:
      blur:
        type: pixgraph.GaussianBlur
        params: {sigma: 3.0}
        inputs: {image: load.image}
    outputs:
      final: blur.image

Loading is safe YAML only: a ``yaml.SafeLoader`` subclass that also records the
line of every mapping key, so any error names the file and line. Tags that would
build Python objects (``!!python/object``) are rejected, as are duplicate keys
(YAML would silently keep the last one).

Older formats are migrated step by step (``MIGRATIONS[n]`` turns version ``n``
into ``n + 1``) on the parsed document, before validation; a version newer than
``FORMAT_VERSION`` is a clear error. ``dump`` writes a canonical text (the nodes
in the graph's order, which is the file's for a loaded graph; params sorted, fixed
key order), so load -> dump -> load gives the same graph and the same text.
"""
from __future__ import annotations

import dataclasses
import errno
import json
import os
import secrets
import sys
from typing import Any, Callable

import yaml

from .graph import Graph, GraphError, NodeInstance, Ref, validate
from .paths import open_write_folder, temp_stem
from .registry import Registry

FORMAT_VERSION = 1
NODE_KEYS = ("type", "params", "inputs")

#: limits on a graph file, so that a small hostile file cannot take minutes or
#: gigabytes (YAML aliases can expand a few hundred bytes into billions of nodes)
MAX_FILE_BYTES = 4 << 20
#: YAML nodes after alias expansion (every scalar, list and mapping counts one)
MAX_YAML_NODES = 200_000
#: nesting of lists and mappings, after alias expansion
MAX_DEPTH = 32
#: characters in one scalar (a path, a string param, a number's text)
MAX_STRING = 10_000


class _Located(dict):
    """A mapping from the file, with the 1-based line of itself and of each key."""

    line: int = 0
    key_lines: dict


class LineLoader(yaml.SafeLoader):
    """SafeLoader that keeps line numbers, refuses duplicate keys, and bounds the
    document (``MAX_DEPTH``, ``MAX_YAML_NODES`` after alias expansion, ``MAX_STRING``)
    before anything is constructed."""

    _depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH + 1:
                raise yaml.composer.ComposerError(None, None, f"nested deeper than {MAX_DEPTH} levels",
                                                  self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def compose_document(self):
        node = super().compose_document()
        _check_expanded(node, {}, 0)
        return node

    def construct_yaml_int(self, node):
        """An integer; one over Python's limit of digits (4300: ``int()`` refuses it), or
        beyond a float's range (a hex ``0xfff...`` or a sexagesimal ``1:0:0:...`` is read
        whatever its size, and ``float()`` or ``str()`` of it raised later: a 500 from the
        server, exit 1) is bad YAML at its line, not a ValueError or OverflowError."""
        try:
            value = super().construct_yaml_int(node)
        except ValueError as e:
            raise yaml.constructor.ConstructorError(None, None, f"integer not read: {e}".split(";")[0],
                                                    node.start_mark) from None
        if abs(value) > sys.float_info.max:
            raise yaml.constructor.ConstructorError(None, None, f"integer not read: {value.bit_length()} bits, "
                                                    "beyond a float's range (about 1.8e308)", node.start_mark)
        return value

    def construct_mapping(self, node, deep=False):
        if not isinstance(node, yaml.MappingNode):
            raise yaml.constructor.ConstructorError(None, None, "expected a mapping", node.start_mark)
        self.flatten_mapping(node)
        out = _Located()
        out.line = node.start_mark.line + 1
        out.key_lines = {}
        for key_node, value_node in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                hash(key)
            except TypeError:
                raise yaml.constructor.ConstructorError(
                    "while reading a mapping", node.start_mark, "found an unhashable key", key_node.start_mark)
            if key in out:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark)
            out[key] = self.construct_object(value_node, deep=deep)
            out.key_lines[key] = key_node.start_mark.line + 1
        return out


LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, LineLoader.construct_mapping)
LineLoader.add_constructor("tag:yaml.org,2002:int", LineLoader.construct_yaml_int)


_IN_PROGRESS = (-1, -1)


def _check_expanded(node, memo: dict, depth: int) -> tuple[int, int]:
    """(nodes, height) of a composed YAML node with aliases expanded; raises
    ``ComposerError`` past the limits or on a self-referencing alias."""
    def fail(what):
        raise yaml.composer.ComposerError(None, None, what, node.start_mark)

    hit = memo.get(id(node))
    if hit is _IN_PROGRESS:
        fail("an alias refers to a node that contains it")
    if hit is None:
        memo[id(node)] = _IN_PROGRESS
        if isinstance(node, yaml.ScalarNode):
            if len(node.value) > MAX_STRING:
                fail(f"a value of {len(node.value)} characters (the limit is {MAX_STRING})")
            hit = (1, 0)
        else:
            children = node.value if isinstance(node, yaml.SequenceNode) else [x for kv in node.value for x in kv]
            count, height = 1, 0
            for child in children:
                c, h = _check_expanded(child, memo, depth + 1)
                count, height = count + c, max(height, h + 1)
                if count > MAX_YAML_NODES:
                    fail(f"more than {MAX_YAML_NODES} values once aliases are expanded")
            hit = (count, height)
        memo[id(node)] = hit
    if depth + hit[1] > MAX_DEPTH:
        fail(f"nested deeper than {MAX_DEPTH} levels once aliases are expanded")
    return hit


def _line(d: Any, key: Any = None) -> int | None:
    if isinstance(d, _Located):
        return d.key_lines.get(key, d.line) if key is not None else d.line
    return None


# -- migrations -----------------------------------------------------------------

def _migrate_0_to_1(doc: dict, fail: Callable[..., GraphError]) -> dict:
    """Format 0 called params ``settings`` and wrote connections as ``[node, output]`` lists."""
    def ref(value, where, line):
        if isinstance(value, list):
            if len(value) != 2 or not all(isinstance(x, str) for x in value):
                raise fail(f"format 0 connection must be [node, output], got {value!r}", line, *where)
            return f"{value[0]}.{value[1]}"
        return value

    nodes = doc.get("nodes")
    if isinstance(nodes, dict):
        for nid, n in nodes.items():
            if not isinstance(n, dict):
                continue
            if "settings" in n:
                if "params" in n:
                    raise fail("has both 'settings' and 'params'", _line(n, "settings"), nid, "params")
                n["params"] = n.pop("settings")
                if isinstance(n, _Located):
                    n.key_lines["params"] = n.key_lines.pop("settings")
            inputs = n.get("inputs")
            if isinstance(inputs, dict):
                for port in list(inputs):
                    inputs[port] = ref(inputs[port], (nid, f"inputs.{port}"), _line(inputs, port))
    outputs = doc.get("outputs")
    if isinstance(outputs, dict):
        for name in list(outputs):
            outputs[name] = ref(outputs[name], (None, f"outputs.{name}"), _line(outputs, name))
    doc["pixgraph"] = 1
    return doc


MIGRATIONS: dict[int, Callable] = {0: _migrate_0_to_1}


# -- load -----------------------------------------------------------------------

def loads(text: str, registry: Registry, *, file: str | None = None, base_dir: str | None = None) -> Graph:
    """Parse graph text (safe YAML), migrate, validate. Raises ``GraphError``."""
    if base_dir is None:
        base_dir = os.path.dirname(os.path.abspath(file)) if file else os.getcwd()

    def fail(message, line=None, node=None, field=None):
        return GraphError(message, file=file, line=line, node=node, field=field)

    if len(text) > MAX_FILE_BYTES:
        raise fail(f"graph file is larger than {MAX_FILE_BYTES} bytes")
    try:
        doc = yaml.load(text, Loader=LineLoader)
    except yaml.MarkedYAMLError as e:
        mark = e.problem_mark or e.context_mark
        context = e.context or ""
        if e.context and e.context_mark is not None and e.problem_mark is not None \
                and e.context_mark.line != e.problem_mark.line:
            context += f" (from line {e.context_mark.line + 1})"
        what = " ".join(x for x in (context, e.problem) if x)
        raise fail(f"invalid YAML: {what}", mark.line + 1 if mark else None) from None
    except yaml.YAMLError as e:
        raise fail(f"invalid YAML: {e}") from None
    except RecursionError:
        raise fail(f"invalid YAML: nested too deeply (the limit is {MAX_DEPTH} levels)") from None
    if not isinstance(doc, dict):
        raise fail("a graph file is a mapping with keys pixgraph, nodes, outputs", 1)
    version = doc.get("pixgraph")
    if "pixgraph" not in doc:
        raise fail("missing format version: the file must start with 'pixgraph: 1'", doc.line)
    if isinstance(version, bool) or not isinstance(version, int):
        raise fail(f"format version must be an integer, got {version!r}", _line(doc, "pixgraph"))
    if version > FORMAT_VERSION:
        raise fail(f"format version {version} is newer than this pixgraph supports ({FORMAT_VERSION}); "
                   "upgrade pixgraph", _line(doc, "pixgraph"))
    if version < min(MIGRATIONS, default=FORMAT_VERSION):
        raise fail(f"format version {version} is too old to migrate", _line(doc, "pixgraph"))
    while version < FORMAT_VERSION:
        doc = MIGRATIONS[version](doc, fail)
        version += 1
    return validate(_to_graph(doc, fail, file, base_dir), registry)


def load(path: str | os.PathLike, registry: Registry) -> Graph:
    """Read and validate a graph file; path params are relative to its folder."""
    path = os.fspath(path)
    if os.path.exists(path) and not os.path.isfile(path):  # a folder, a FIFO, a device
        raise GraphError("cannot read graph file: not a regular file", file=path)
    try:
        with open(path, "rb") as f:
            data = f.read(MAX_FILE_BYTES + 1)
        if len(data) > MAX_FILE_BYTES:
            raise GraphError(f"graph file is larger than {MAX_FILE_BYTES} bytes", file=path)
        text = data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise GraphError(f"cannot read graph file: {e.strerror if isinstance(e, OSError) else e}",
                         file=path) from None
    return loads(text, registry, file=path)


def _to_graph(doc: dict, fail, file, base_dir) -> Graph:
    lines: dict[str, int] = {}
    for key in doc:
        if key not in ("pixgraph", "nodes", "outputs"):
            raise fail(f"unknown top-level key {key!r} (expected pixgraph, nodes, outputs)", _line(doc, key))
    raw_nodes = doc.get("nodes") or {}
    if not isinstance(raw_nodes, dict):
        raise fail("'nodes' must be a mapping of node id to node", _line(doc, "nodes"))
    nodes = {}
    for nid, n in raw_nodes.items():
        line = _line(raw_nodes, nid)
        if not isinstance(nid, str):
            raise fail(f"node id must be a string, got {nid!r}", line)
        lines[f"nodes.{nid}"] = line
        if not isinstance(n, dict):
            raise fail("a node is a mapping with type, params, inputs", line, nid)
        for key in n:
            if key not in NODE_KEYS:
                raise fail(f"unknown key {key!r} (expected {', '.join(NODE_KEYS)})", _line(n, key), nid, str(key))
            lines[f"nodes.{nid}.{key}"] = _line(n, key)
        if not isinstance(n.get("type"), str):
            raise fail("'type' is missing or not a string", _line(n, "type"), nid, "type")
        params = n.get("params") or {}
        inputs = n.get("inputs") or {}
        if not isinstance(params, dict):
            raise fail("'params' must be a mapping", _line(n, "params"), nid, "params")
        if not isinstance(inputs, dict):
            raise fail("'inputs' must be a mapping of input port to 'node.output'", _line(n, "inputs"), nid, "inputs")
        for k in params:
            if not isinstance(k, str):
                raise fail(f"param name must be a string, got {k!r}", _line(params, k), nid, "params")
            lines[f"nodes.{nid}.params.{k}"] = _line(params, k)
        refs = {}
        for k, v in inputs.items():
            lines[f"nodes.{nid}.inputs.{k}"] = _line(inputs, k)
            try:
                refs[str(k)] = Ref.parse(v)
            except ValueError as e:
                raise fail(str(e), _line(inputs, k), nid, f"inputs.{k}") from None
        nodes[nid] = NodeInstance(nid, n["type"], {k: _plain(v) for k, v in params.items()}, refs)
    raw_outputs = doc.get("outputs") or {}
    if not isinstance(raw_outputs, dict):
        raise fail("'outputs' must be a mapping of name to 'node.output'", _line(doc, "outputs"))
    outputs = {}
    for name, v in raw_outputs.items():
        lines[f"outputs.{name}"] = _line(raw_outputs, name)
        try:
            outputs[str(name)] = Ref.parse(v)
        except ValueError as e:
            raise fail(str(e), _line(raw_outputs, name), None, f"outputs.{name}") from None
    return Graph(nodes, outputs, file=file, base_dir=base_dir, lines=lines)


def _plain(v: Any) -> Any:
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_plain(x) for x in v]
    return v


# -- dump -----------------------------------------------------------------------

def to_document(graph: Graph) -> dict:
    """The canonical plain-data form of a graph: its nodes in the graph's order (a
    loaded graph's is its file's, so a graph saved and opened again lists its nodes as
    they were written), params, inputs and outputs sorted."""
    nodes = {}
    for nid in graph.nodes:
        inst = graph.nodes[nid]
        n: dict[str, Any] = {"type": inst.type}
        if inst.params:
            n["params"] = {k: list(v) if isinstance(v, tuple) else v for k, v in sorted(inst.params.items())}
        if inst.inputs:
            n["inputs"] = {k: str(v) for k, v in sorted(inst.inputs.items())}
        nodes[nid] = n
    doc: dict[str, Any] = {"pixgraph": FORMAT_VERSION, "nodes": nodes}
    if graph.outputs:
        doc["outputs"] = {k: str(v) for k, v in sorted(graph.outputs.items())}
    return doc


def dumps(graph: Graph) -> str:
    """Canonical YAML text: stable under load -> dump."""
    return yaml.safe_dump(to_document(graph), sort_keys=False, default_flow_style=False,
                          allow_unicode=True, width=100)


def dump(graph: Graph, path: str | os.PathLike, registry: Registry | None = None) -> None:
    """Write ``graph`` to ``path`` atomically, never through a symlink.

    With ``registry``, relative file params (kind ``path``) are rewritten
    relative to the new file's folder, so the saved graph finds the same files
    wherever it is written; without it they are written as given.

    The folder is opened by ``paths.open_write_folder`` (for a ``WritePath``, the
    folder the path policy checked; no symlink followed on the way), the text goes
    to a temporary created there with ``O_EXCL | O_NOFOLLOW`` under a random name,
    which is renamed into place in that folder: a symlink planted in the folder (at
    a temporary's name, or at ``path`` itself, which is replaced) is never written
    through. Raises ``PathError`` when a folder on the way became a symlink.
    """
    if registry is not None:
        graph = rebase_paths(graph, registry, os.path.dirname(os.path.abspath(path)))
    text = dumps(graph)
    real = getattr(path, "real", None) or os.path.abspath(path)
    if not os.path.isdir(os.path.dirname(real)):     # as open() would: no folders made
        raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), os.fspath(path))
    folder, name = open_write_folder(path)
    try:
        folder.write_replace(name, text.encode("utf-8"), f".{temp_stem(name)}.tmp-{os.getpid()}-{secrets.token_hex(4)}",
                            0o666)
    finally:
        folder.close()


def rebase_paths(graph: Graph, registry: Registry, new_base: str) -> Graph:
    """The same graph with relative path params re-expressed relative to ``new_base``."""
    nodes = {}
    for nid, inst in graph.nodes.items():
        spec = registry.get(inst.type)
        params = dict(inst.params)
        for name, value in inst.params.items():
            p = spec.param(name)
            if p is not None and p.kind == "path" and isinstance(value, str) and not os.path.isabs(value):
                params[name] = os.path.relpath(os.path.join(graph.base_dir, value), new_base)
        nodes[nid] = dataclasses.replace(inst, params=params)
    return dataclasses.replace(graph, nodes=nodes, base_dir=new_base)


# -- schema ---------------------------------------------------------------------

def json_schema(registry: Registry) -> dict:
    """JSON Schema (draft 2020-12) of format-1 graph files for the registered node types."""
    ref_pattern = r"^[A-Za-z_][A-Za-z0-9_\-]*\.[A-Za-z_][A-Za-z0-9_]*$"
    variants = []
    for spec in registry.specs():
        params = {p.name: p.json_schema() for p in spec.params}
        required_params = [p.name for p in spec.params if p.required]
        inputs = {p.name: {"type": "string", "pattern": ref_pattern,
                           "description": f"{p.type.type_name()}: {p.doc}".rstrip(": ")}
                  for p in spec.inputs}
        required_inputs = [p.name for p in spec.inputs if not p.optional]
        node_schema: dict[str, Any] = {
            "type": "object",
            "description": spec.summary,
            "properties": {
                "type": {"const": spec.type_id},
                "params": {"type": "object", "properties": params, "additionalProperties": False,
                           **({"required": required_params} if required_params else {})},
                "inputs": {"type": "object", "properties": inputs, "additionalProperties": False,
                           **({"required": required_inputs} if required_inputs else {})},
            },
            "required": ["type"] + (["params"] if required_params else []) + (["inputs"] if required_inputs else []),
            "additionalProperties": False,
        }
        variants.append(node_schema)
    return {
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "pixgraph graph file",
        "type": "object",
        "properties": {
            "pixgraph": {"const": FORMAT_VERSION},
            "nodes": {"type": "object",
                      "propertyNames": {"pattern": r"^[A-Za-z_][A-Za-z0-9_\-]*$"},
                      "additionalProperties": {"oneOf": variants} if variants else {"type": "object"}},
            "outputs": {"type": "object", "additionalProperties": {"type": "string", "pattern": ref_pattern}},
        },
        "required": ["pixgraph", "nodes"],
        "additionalProperties": False,
    }


def schema_text(registry: Registry) -> str:
    return json.dumps(json_schema(registry), indent=2, sort_keys=True) + "\n"
