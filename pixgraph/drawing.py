"""Pictures of a graph: Graphviz DOT text and a self-contained SVG (``pixgraph graph``).

The SVG needs no Graphviz: nodes are placed in layers by networkx
(``topological_generations``: a node sits one layer right of its deepest input),
ordered within a layer by the mean position of their inputs (fewer crossings),
and edges are drawn as curves from an output's side of a box to an input's.
Each box shows the node id, its type and the params the graph sets; the graph's
named outputs are the green boxes on the right.
"""
from __future__ import annotations

import html
from typing import Any

from .graph import Graph, dag
from .registry import Registry

BOX_W, LINE_H, PAD, GAP_X, GAP_Y = 210, 16, 8, 70, 22
MAX_PARAMS = 4


def _param_lines(graph: Graph, nid: str) -> list[str]:
    items = sorted(graph.nodes[nid].params.items())
    lines = [f"{k} = {_short(v)}" for k, v in items[:MAX_PARAMS]]
    if len(items) > MAX_PARAMS:
        lines.append(f"... {len(items) - MAX_PARAMS} more")
    return lines


def _short(v: Any, limit: int = 22) -> str:
    text = "[" + ", ".join(f"{x:g}" if isinstance(x, float) else str(x) for x in v) + "]" \
        if isinstance(v, (list, tuple)) else (f"{v:g}" if isinstance(v, float) else str(v))
    return text if len(text) <= limit else text[:limit - 3] + "..."


def to_dot(graph: Graph, registry: Registry | None = None) -> str:
    """The graph in Graphviz DOT: one box per node (id, type), one edge per
    connection labelled ``output -> input``, the named outputs as ellipses."""
    def esc(s: str) -> str:
        return str(s).replace("\\", "\\\\").replace('"', '\\"')

    def q(s: str) -> str:
        return '"' + esc(s) + '"'

    out = ["digraph pixgraph {", "  rankdir=LR;", '  node [shape=box, style="rounded,filled", fillcolor="#eef2f7", '
           'fontname="Helvetica"];', '  edge [fontname="Helvetica", fontsize=10];']
    for nid, inst in graph.nodes.items():
        sink = registry is not None and inst.type in registry and registry.get(inst.type).side_effects
        label = "\\n".join(esc(x) for x in [nid, inst.type] + _param_lines(graph, nid))  # DOT's line break
        out.append(f'  {q(nid)} [label="{label}"'
                   + (', fillcolor="#fde7d2"' if sink else "") + "];")
    for nid, inst in graph.nodes.items():
        for port, ref in inst.inputs.items():
            out.append(f"  {q(ref.node)} -> {q(nid)} [label={q(f'{ref.output} -> {port}')}];")
    for name, ref in graph.outputs.items():
        out.append(f'  {q("output:" + name)} [label={q(name)}, shape=ellipse, fillcolor="#d8f0d8"];')
        out.append(f"  {q(ref.node)} -> {q('output:' + name)} [label={q(ref.output)}];")
    out.append("}")
    return "\n".join(out) + "\n"


def layout(graph: Graph) -> dict[str, tuple[int, int]]:
    """``{node id: (layer, row)}``: layers from networkx's topological generations,
    rows ordered by the mean row of each node's inputs (ties in file order)."""
    import networkx as nx

    g = dag(graph)
    index = {n: i for i, n in enumerate(graph.nodes)}
    pos: dict[str, tuple[int, int]] = {}
    for layer, names in enumerate(nx.topological_generations(g)):
        def weight(n):
            preds = [pos[p][1] for p in g.predecessors(n) if p in pos]
            return (sum(preds) / len(preds) if preds else -1.0, index[n])
        for row, n in enumerate(sorted(names, key=weight)):
            pos[n] = (layer, row)
    return pos


def to_svg(graph: Graph, registry: Registry | None = None, title: str | None = None) -> str:
    """A self-contained SVG picture of the graph (see the module doc). Each box lists
    the node's connected inputs on the left and used outputs on the right, where
    the edges meet it."""
    pos = layout(graph)
    head = {nid: [nid, graph.nodes[nid].type] + _param_lines(graph, nid) for nid in graph.nodes}
    ins = {nid: list(inst.inputs) for nid, inst in graph.nodes.items()}
    outs_used: dict[str, list[str]] = {nid: [] for nid in graph.nodes}
    for inst in graph.nodes.values():
        for ref in inst.inputs.values():
            if ref.node in outs_used and ref.output not in outs_used[ref.node]:
                outs_used[ref.node].append(ref.output)
    for ref in graph.outputs.values():
        if ref.node in outs_used and ref.output not in outs_used[ref.node]:
            outs_used[ref.node].append(ref.output)
    rows = {nid: max(len(ins[nid]), len(outs_used[nid])) for nid in graph.nodes}
    box_h = {nid: PAD * 2 + LINE_H * (len(head[nid]) + rows[nid]) + (4 if rows[nid] else 0) for nid in graph.nodes}
    n_layers = max((layer for layer, _ in pos.values()), default=-1) + 1
    xy: dict[str, tuple[float, float]] = {}
    top = 40 if title else 16
    for layer in range(n_layers):
        y = top
        for nid in sorted((n for n in pos if pos[n][0] == layer), key=lambda n: pos[n][1]):
            xy[nid] = (16 + layer * (BOX_W + GAP_X), y)
            y += box_h[nid] + GAP_Y

    def port_y(nid: str, i: int) -> float:  # the middle of port row i of a box
        return xy[nid][1] + PAD + LINE_H * (len(head[nid]) + i) + 4 + LINE_H / 2

    out_x = 16 + n_layers * (BOX_W + GAP_X)
    outs: dict[str, tuple[float, float]] = {}
    y_next = top
    for name, ref in graph.outputs.items():
        y = max(port_y(ref.node, outs_used[ref.node].index(ref.output)) - LINE_H, y_next)
        outs[name] = (out_x, y)
        y_next = y + LINE_H * 2 + 8
    width = out_x + (120 if outs else 0) + 16
    height = max([y + box_h[n] for n, (_, y) in xy.items()] + [y + LINE_H * 2 for _, y in outs.values()]
                 + [top]) + 16
    e = html.escape
    svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0f}" height="{height:.0f}" '
           f'viewBox="0 0 {width:.0f} {height:.0f}" font-family="Helvetica, Arial, sans-serif" font-size="12">',
           '<defs><marker id="arrow" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="6" markerHeight="6" '
           'orient="auto-start-reverse"><path d="M 0 0 L 10 5 L 0 10 z" fill="#56606b"/></marker></defs>',
           f'<rect width="{width:.0f}" height="{height:.0f}" fill="#ffffff"/>']
    if title:
        svg.append(f'<text x="16" y="24" font-size="15" font-weight="bold">{e(title)}</text>')

    def curve(x1, y1, x2, y2, cls, what):
        mx = (x1 + x2) / 2
        svg.append(f'<path class="{cls}" data-edge="{e(what)}" d="M {x1:.1f} {y1:.1f} C {mx:.1f} {y1:.1f}, '
                   f'{mx:.1f} {y2:.1f}, {x2:.1f} {y2:.1f}" fill="none" stroke="#56606b" stroke-width="1.3" '
                   'marker-end="url(#arrow)"/>')

    for nid, inst in graph.nodes.items():  # edges first, so boxes sit on top
        for i, (port, ref) in enumerate(inst.inputs.items()):
            x1, _ = xy[ref.node]
            curve(x1 + BOX_W, port_y(ref.node, outs_used[ref.node].index(ref.output)), xy[nid][0],
                  port_y(nid, i), "edge", f"{ref} -> {nid}.{port}")
    for name, ref in graph.outputs.items():
        x1, _ = xy[ref.node]
        curve(x1 + BOX_W, port_y(ref.node, outs_used[ref.node].index(ref.output)), outs[name][0],
              outs[name][1] + LINE_H, "edge output-edge", f"{ref} -> {name}")
    for nid in graph.nodes:
        x, y = xy[nid]
        t = graph.nodes[nid].type
        sink = registry is not None and t in registry and registry.get(t).side_effects
        fill = "#fde7d2" if sink else "#eef2f7"
        svg.append(f'<g class="node" data-id="{e(nid)}"><rect x="{x:.0f}" y="{y:.0f}" width="{BOX_W}" '
                   f'height="{box_h[nid]}" rx="7" fill="{fill}" stroke="#8a96a3"/>')
        for i, text in enumerate(head[nid]):
            style = ' font-weight="bold"' if i == 0 else (' fill="#3b6ea5"' if i == 1 else ' fill="#444"')
            svg.append(f'<text x="{x + PAD:.0f}" y="{y + PAD + LINE_H * (i + 1) - 4:.0f}"{style}>{e(text)}</text>')
        if rows[nid]:
            ly = y + PAD + LINE_H * len(head[nid]) + 2
            svg.append(f'<line x1="{x:.0f}" y1="{ly:.0f}" x2="{x + BOX_W:.0f}" y2="{ly:.0f}" stroke="#c9d1da"/>')
        for i, port in enumerate(ins[nid]):
            svg.append(f'<text class="in" x="{x + PAD:.0f}" y="{port_y(nid, i) + 4:.0f}" font-size="11" '
                       f'fill="#56606b">▸ {e(port)}</text>')
        for i, port in enumerate(outs_used[nid]):
            svg.append(f'<text class="out" x="{x + BOX_W - PAD:.0f}" y="{port_y(nid, i) + 4:.0f}" font-size="11" '
                       f'text-anchor="end" fill="#56606b">{e(port)} ▸</text>')
        svg.append("</g>")
    for name, (x, y) in outs.items():
        svg.append(f'<g class="graph-output" data-id="{e(name)}"><rect x="{x:.0f}" y="{y:.0f}" width="100" '
                   f'height="{LINE_H * 2}" rx="{LINE_H}" fill="#d8f0d8" stroke="#6aa36a"/>'
                   f'<text x="{x + 50:.0f}" y="{y + LINE_H + 4:.0f}" text-anchor="middle" '
                   f'font-weight="bold">{e(name)}</text></g>')
    svg.append("</svg>")
    return "\n".join(svg) + "\n"
