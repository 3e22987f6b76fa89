"""Items: rows bound to a graph and to output files inside their output folders.

An output template (``out/{row}_{name}.png``) names an *output folder*: the
folder of its text before the first ``{field}`` (``out``; the current folder for
``{row}.png``). Every file the template makes for a row must lie inside that
folder once symlinks are resolved: a row id or column such as
``../../outside/pwned`` is refused before anything runs, and two outputs that
reach the same file (through a symlinked folder, too) are refused as well.
"""
from __future__ import annotations

import dataclasses
import os
import string
from typing import Any, Mapping, Sequence

from pixgraph.graph import Graph, GraphError, split_param
from pixgraph.paths import NAME_MAX, bad_characters, quote

from .rows import BatchError, Row, short

DEFAULT_TEMPLATE = "out/{row}_{name}.png"


@dataclasses.dataclass(frozen=True)
class Item:
    """One unit of work: a row's overrides (paths absolute) and its output files."""

    index: int
    row: str
    params: Mapping[str, Any]
    #: output name (graph output or NODE.OUTPUT) -> absolute file path
    outputs: Mapping[str, str]
    source: str = ""
    #: output name -> the real output folder of its template (what a batch locks)
    folders: Mapping[str, str] = dataclasses.field(default_factory=dict)


def parse_output_options(options: Sequence[str]) -> dict[str, str] | None:
    """``-o NAME=TEMPLATE`` options -> ``{name: template}`` (None when none given);
    the same parser as ``pixgraph run -o``."""
    from pixgraph.options import parse_output_options as parse
    from pixgraph.errors import UsageError

    if not options:
        return None
    try:
        return parse(options, "TEMPLATE")
    except UsageError as e:
        raise BatchError(str(e)) from None


def template_folder(template: str) -> str:
    """The output folder a template names (absolute, symlinks resolved): the folder
    of its literal text before the first field."""
    try:
        first = next(iter(string.Formatter().parse(template)), ("", None, None, None))[0] or ""
    except ValueError as e:
        raise BatchError(f"output template {template!r}: {e}") from None
    if first == template:  # no field at all: the file's own folder
        first = os.path.dirname(template) + os.sep if os.path.dirname(template) else ""
    folder = first if first.endswith(os.sep) or (os.altsep and first.endswith(os.altsep)) \
        else os.path.dirname(first)
    return os.path.realpath(os.path.abspath(folder or os.curdir))


def _inside(path: str, folder: str) -> bool:
    try:
        return os.path.commonpath([path, folder]) == folder
    except ValueError:  # different drives
        return False


def make_items(graph: Graph, rows: Sequence[Row], registry, outputs: Mapping[str, str] | Sequence[str] | None = None,
               template: str = DEFAULT_TEMPLATE, manifest_dir: str | None = None,
               params: Mapping[str, Any] | None = None) -> list[Item]:
    """Bind rows to ``graph``: check the override columns name real node params,
    resolve relative path params against ``manifest_dir`` and fill in the output
    templates (fields: ``row``, ``index``, ``name``, ``stem`` = the file stem of the
    row's first path param, each override as ``node_param`` and each extra column).
    Each file must land inside its template's output folder and no two outputs may
    be the same file (compared by real path): else ``BatchError``, before anything runs.

    outputs: ``{name: template}``, a list of names (all with ``template``), or
        ``None`` for every image-valued graph output.
    params: overrides shared by every row (applied first).
    """
    if outputs is None:
        outputs = image_outputs(graph, registry)
        if not outputs:
            raise BatchError("the graph has no image outputs: name outputs with -o NAME=TEMPLATE")
    if not isinstance(outputs, Mapping):
        outputs = {name: template for name in outputs}
    folders = {name: template_folder(tmpl) for name, tmpl in outputs.items()}
    shared = dict(params or {})
    width = max(4, len(str(len(rows) - 1)))
    items, seen = [], {}
    for i, row in enumerate(rows):
        merged = dict(shared)
        for name, value in row.params.items():
            merged[name] = _resolve_param(graph, registry, name, value, manifest_dir, row.source)
        rid = row.id or f"{i:0{width}d}"
        fields = dict(row.fields)
        fields.update({name.replace(".", "_"): short(v) for name, v in row.params.items()})
        stem = next((os.path.splitext(os.path.basename(v))[0] for n, v in merged.items()
                     if is_path_param(graph, registry, n) and isinstance(v, str) and n in row.params), rid)
        fields.update(row=rid, index=i, stem=stem)
        files = {}
        for name, tmpl in outputs.items():
            path = _fill(tmpl, fields, name)
            why = bad_characters(path)
            if why:
                raise BatchError(f"{row.source or 'row ' + rid}: output {name}: path {quote(path)} {why}")
            path = os.path.abspath(path)
            size = len(os.path.basename(path).encode("utf-8", "surrogateescape")) + len(".json")
            if size > NAME_MAX:
                raise BatchError(f"{row.source or 'row ' + rid}: output {name}: the file name of {quote(path)} "
                                 f"with its sidecar's '.json' is {size} bytes, over the {NAME_MAX} a file "
                                 f"name may have")
            real = os.path.realpath(path)
            if not _inside(real, folders[name]):
                raise BatchError(f"{row.source or 'row ' + rid}: output {name}: {quote(path)} is outside the "
                                 f"output folder {folders[name]} of template {tmpl!r} (row ids and columns "
                                 f"may not leave it)")
            if real in seen:
                raise BatchError(f"row {seen[real][0]} output {seen[real][1]} and row {rid} output {name} both "
                                 f"write {real}: put {{row}} or {{stem}} in each output template")
            seen[real] = (rid, name)
            files[name] = path
        items.append(Item(i, rid, merged, files, row.source, folders))
    return items


def _fill(tmpl: str, fields: Mapping[str, Any], name: str) -> str:
    try:
        return string.Formatter().vformat(tmpl, (), {**fields, "name": name.replace(".", "_")})
    except (KeyError, IndexError, ValueError, AttributeError, TypeError) as e:
        raise BatchError(f"output template {tmpl!r}: {type(e).__name__} {e}; fields: "
                         f"{', '.join(sorted({*fields, 'name'}))}") from None


def output_folders(items: Sequence[Item]) -> list[str]:
    """The real output folders of the items' templates, sorted (what a batch locks;
    the folder of each file for items made without templates)."""
    folders = set()
    for it in items:
        for name, p in it.outputs.items():
            folders.add(it.folders.get(name) or os.path.dirname(os.path.realpath(p)))
    return sorted(folders)


def image_outputs(graph: Graph, registry) -> list[str]:
    """The graph outputs that can be written to a file (their port type has ``write``)."""
    names = []
    for name, ref in graph.outputs.items():
        port = registry.get(graph.nodes[ref.node].type).output(ref.output)
        if port is not None and getattr(port.type, "write", None) is not None:
            names.append(name)
    return names


def is_path_param(graph: Graph, registry, name: str) -> bool:
    try:
        node, pname = split_param(name)
    except GraphError:
        return False
    inst = graph.nodes.get(node)
    if inst is None:
        return False
    p = registry.get(inst.type).param(pname)
    return p is not None and p.kind == "path"


def _resolve_param(graph, registry, name, value, manifest_dir, source):
    try:
        node, pname = split_param(name, what="column")
    except GraphError as e:
        raise BatchError(f"{source}: {e.message}") from None
    if node not in graph.nodes:
        raise BatchError(f"{source}: column {name!r}: no node {node!r} in the graph "
                         f"(nodes: {', '.join(graph.nodes)})")
    spec = registry.get(graph.nodes[node].type)
    if spec.param(pname) is None:
        raise BatchError(f"{source}: column {name!r}: node {node!r} ({spec.type_id}) has no param {pname!r}")
    if is_path_param(graph, registry, name) and isinstance(value, str) and value and not os.path.isabs(value):
        return os.path.abspath(os.path.join(manifest_dir or os.getcwd(), value))
    return value


def user_files(graph: Graph, registry, items: Sequence[Item]) -> list[str]:
    """The files that rows' path overrides name: the user's own (from a manifest,
    a sweep or ``--set``), allowed by the path policy like ``pixgraph run --set``."""
    files = set()
    for item in items:
        for name, value in item.params.items():
            if isinstance(value, str) and value and is_path_param(graph, registry, name) \
                    and not bad_characters(value):
                files.add(graph.resolve_path(value))
    return sorted(files)
