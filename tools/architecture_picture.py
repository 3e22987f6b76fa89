"""Draw docs/img/architecture.svg: how data flows from a graph file, the browser
page or a host to a kernel and back, drawn by pixgraph's own ``pixgraph graph``
drawing (``pixgraph.drawing.to_svg``) from a graph whose boxes are the modules.

    python tools/architecture_picture.py [OUT.svg]

tests/test_architecture_doc.py checks the committed picture is this script's output.
"""
from __future__ import annotations

import os
import sys

from pixgraph.drawing import to_svg
from pixgraph.graph import Graph, NodeInstance, Ref

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "docs", "img", "architecture.svg")


def _n(nid, where, inputs=None, **notes):
    return NodeInstance(nid, where, notes, {k: Ref.parse(v) for k, v in (inputs or {}).items()})


def picture() -> str:
    nodes = [
        _n("graph_file", "pixgraph.fileio.load", reads="safe YAML", then="migrations"),
        _n("browser_page", "pixgraph_serve (HTTP)", sends="param edits"),
        _n("host", "Blender add-on / Python", gives="bind arrays"),
        _n("Session", "pixgraph.session",
           {"file": "graph_file.graph", "edits": "browser_page.params", "arrays": "host.bind"}),
        _n("validate", "pixgraph.graph + networkx", {"graph": "Session.graph"},
           checks="types, params, cycles"),
        _n("Engine_plan", "pixgraph.engine + resolve", {"graph": "validate.graph", "registry": "registry.specs"},
           key="versions, code, params"),
        _n("registry", "pixgraph.registry", finds="entry points"),
        _n("caches", "pixgraph.cache", holds="memory + disk entries"),
        _n("Engine_run", "pixgraph.engine + scheduler", {"plan": "Engine_plan.plan", "hits": "caches.values"},
           order="networkx, workers"),
        _n("Node_compute", "pixgraph_nodes/<node>.py", {"inputs": "Engine_run.inputs"},
           hooks="compute infer bind ..."),
        _n("kernel", "pixgraph_nodes/ops", {"arrays": "Node_compute.arrays"}, runs="OpenCL | numpy | torch"),
        _n("RunResult", "pixgraph.plan", {"outputs": "kernel.outputs"}, says="ran, cached, seconds"),
    ]
    outputs = {"files (-o, batch)": Ref("RunResult", "values"), "page PNG": Ref("RunResult", "image"),
               "host arrays": Ref("RunResult", "arrays")}
    g = Graph({n.id: n for n in nodes}, outputs, base_dir=ROOT)
    return to_svg(g, None, "pixgraph: from a graph to a kernel and back")


def main() -> None:
    out = sys.argv[1] if len(sys.argv) > 1 else OUT
    with open(out, "w", encoding="utf-8") as f:
        f.write(picture())
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
