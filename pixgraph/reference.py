"""Node reference text and Markdown, generated from the declarations alone.

Used by ``pixgraph nodes NAME`` and ``pixgraph nodes --markdown > docs/nodes.md``.
The output is deterministic: nodes sorted by type id, ports and params in
declaration order, no timestamps or paths.
"""
from __future__ import annotations

import inspect

from .node import NodeSpec, ParamSpec
from .registry import Registry


def _default(p: ParamSpec) -> str:
    if p.required:
        return "required"
    d = p.default
    if isinstance(d, tuple):
        d = list(d)
    if isinstance(d, bool):
        return "true" if d else "false"
    return repr(d) if isinstance(d, str) else str(d)


def _constraints(p: ParamSpec) -> str:
    parts = []
    if p.min is not None or p.max is not None:
        lo = "-inf" if p.min is None else f"{p.min:g}"
        hi = "inf" if p.max is None else f"{p.max:g}"
        parts.append(f"[{lo}, {hi}]")
    if p.choices:
        parts.append(" | ".join(p.choices))
    if p.length is not None:
        parts.append(f"{p.length} values")
    if p.kind == "path":
        parts.append("file written by the node" if p.writes else "file read; its content is hashed")
    if not p.cache:
        parts.append("does not affect the result")
    return "; ".join(parts)


def text(spec: NodeSpec, source: str = "") -> str:
    """Plain-text reference of one node type."""
    lines = [f"{spec.type_id} (version {spec.version}, impl {spec.impl_version})"]
    doc = inspect.cleandoc(spec.doc) if spec.doc else ""
    if doc:
        lines += ["", *("  " + ln if ln else "" for ln in doc.splitlines())]
    if spec.side_effects:
        lines += ["", "  Sink: writes files; runs whenever its output is requested, never cached."]
    for title, ports in (("Inputs", spec.inputs), ("Outputs", spec.outputs)):
        lines += ["", f"{title}:"]
        if not ports:
            lines.append("  (none)")
        for p in ports:
            opt = " (optional)" if p.optional else ""
            lines.append(f"  {p.name}: {p.type.type_name()}{opt}" + (f" - {p.doc}" if p.doc else ""))
            lines.append(f"      {p.type.describe}")
    lines += ["", "Params:"]
    if not spec.params:
        lines.append("  (none)")
    for p in spec.params:
        unit = f" [{p.unit}]" if p.unit else ""
        lines.append(f"  {p.name}: {p.kind} = {_default(p)}{unit}" + (f" - {p.doc}" if p.doc else ""))
        c = _constraints(p)
        if c:
            lines.append(f"      {c}")
    if source:
        lines += ["", f"Source: {source}"]
    return "\n".join(lines) + "\n"


def _cell(s: str) -> str:
    return s.replace("|", "\\|").replace("\n", " ")


def markdown_section(spec: NodeSpec) -> str:
    """The Markdown section of one node type, from its ``## type_id`` heading on."""
    out = [f"## {spec.type_id}", "",
           f"Version {spec.version}, impl_version {spec.impl_version}."
           + (" Sink: runs whenever requested, never cached." if spec.side_effects else ""), ""]
    if spec.doc:
        out += [inspect.cleandoc(spec.doc), ""]
    for title, ports in (("Inputs", spec.inputs), ("Outputs", spec.outputs)):
        if not ports:
            continue
        out += [f"**{title}**", "", "| name | type | doc |", "|---|---|---|"]
        for p in ports:
            opt = " (optional)" if p.optional else ""
            out.append(f"| `{p.name}` | {p.type.type_name()}{opt} | {_cell(p.doc or p.type.describe)} |")
        out.append("")
    if spec.params:
        out += ["**Params**", "", "| name | kind | default | range / choices | unit | doc |",
                "|---|---|---|---|---|---|"]
        for p in spec.params:
            out.append(f"| `{p.name}` | {p.kind} | {_cell(_default(p))} | {_cell(_constraints(p))} | "
                       f"{_cell(p.unit)} | {_cell(p.doc)} |")
        out.append("")
    return "\n".join(out).rstrip("\n") + "\n"


def markdown(registry: Registry) -> str:
    """The whole node reference as Markdown (``docs/nodes.md``)."""
    out = ["# Node reference", "",
           "Generated from the node declarations by `pixgraph nodes --markdown`; do not edit by hand.", ""]
    for spec in registry.specs():
        out.append(f"- [`{spec.type_id}`](#{spec.type_id.lower().replace('.', '')}) - {spec.summary}")
    out += ["", "## Port types", "",
            "What flows along an edge (`Registry.port_types()`: the engine's own and those of these nodes' "
            "ports). An output feeds an input of its own type, of a base type, or `Any`.", "",
            "| type | base | value | file |", "|---|---|---|---|"]
    for name, t in sorted(registry.port_types().items()):
        base = next((b.type_name() for b in t.__mro__[1:] if b in registry.port_types().values()), "")
        writes = "written by `-o`" if t.write is not None else ""
        out.append(f"| {name} | {base} | {_cell(t.describe)} | {writes} |")
    text = "\n".join(out) + "\n"
    for spec in registry.specs():
        text += "\n" + markdown_section(spec)
    return text


def as_dict(spec: NodeSpec) -> dict:
    """One node type's declaration as plain JSON data (``pixgraph nodes --json``, the server's UI)."""
    def port(p):
        return {"name": p.name, "type": p.type.type_name(), "optional": p.optional, "doc": p.doc}

    def prm(p: ParamSpec):
        d = p.default
        return {"name": p.name, "kind": p.kind, "default": list(d) if isinstance(d, tuple) else d,
                "required": p.required, "min": p.min, "max": p.max,
                "choices": list(p.choices) if p.choices is not None else None, "length": p.length,
                "unit": p.unit, "doc": p.doc, "cache": p.cache, "writes": p.writes}

    return {"type": spec.type_id, "version": spec.version, "impl_version": spec.impl_version,
            "summary": spec.summary, "doc": inspect.cleandoc(spec.doc) if spec.doc else "",
            "side_effects": spec.side_effects, "inputs": [port(p) for p in spec.inputs],
            "outputs": [port(p) for p in spec.outputs], "params": [prm(p) for p in spec.params]}
