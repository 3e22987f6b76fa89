"""The numbers behind the server's byte bounds (issue 24's undo/run records and JSON
bodies: docs/server.md, "Undo" and "Errors"):

    python benchmarks/serve_bounds_bench.py [--nodes 8000] [--repeat 5]

graph         an N-node graph of ``pixgraph.Constant`` with 3 params (width, height, a
              4-value color), loaded from YAML (as the server holds a posted graph,
              with its source lines) and built in Python (no lines): what it holds
              (tracemalloc, after a collection), ``history.graph_bytes``'s estimate
              and its time (median of --repeat).
undo          20 edits of the loaded graph recorded in ``History(100)`` (64 MiB) and
              added to ``Runs()`` (64 MiB): steps and runs kept, estimated bytes.
json          what the event loop did before a5c829a for a 24 MB body of a
              2-million-point list: ``json.loads`` and ``check_depth`` (median of 3).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
from _machine import cpu_model  # noqa: E402
from test_serve_undo_bytes import big_graph as built, held_by as held  # noqa: E402

from pixgraph import fileio  # noqa: E402
from pixgraph.registry import Registry  # noqa: E402
from pixgraph_serve.history import History, Step, graph_bytes  # noqa: E402
from pixgraph_serve.runs import Runs  # noqa: E402
from pixgraph_serve.state import check_depth  # noqa: E402

MiB = 1 << 20


def yaml_text(n: int, tag: int) -> str:
    return "pixgraph: 1\nnodes:\n" + "".join(
        f"  c{i}: {{type: pixgraph.Constant, params: {{width: {8 + tag}, height: 8, color: [0.1, 0.2, 0.3, 1]}}}}\n"
        for i in range(n)) + "outputs: {final: c0.image}\n"


def median_s(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--nodes", type=int, default=8000)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    reg = Registry.discover()
    print(f"machine: {cpu_model()}, load average {os.getloadavg()[0]:.2f}")
    fileio.loads(yaml_text(10, 0), reg)
    for what, make in (("loaded", lambda: fileio.loads(yaml_text(a.nodes, 0), reg)),
                       ("built", lambda: built(a.nodes, 0))):
        g, b = held(make)
        est = graph_bytes(g)
        t = median_s(lambda: graph_bytes(g), a.repeat)
        print(f"graph {what:6s} {a.nodes} nodes: holds {b / MiB:.1f} MiB, graph_bytes {est / MiB:.1f} MiB "
              f"({est / b:.2f} x), graph_bytes median {t * 1000:.0f} ms")
    h, runs, graphs = History(100), Runs(), [fileio.loads(yaml_text(a.nodes, 0), reg)]
    for k in range(1, 21):
        graphs.append(fileio.loads(yaml_text(a.nodes, k), reg))
        h.record(Step(graphs[-2], {}), graphs[-1], None)
        runs.add(graphs[-1], "final", ["final"])
        graphs[-2] = None
    print(f"undo 20 edits of the loaded graph: {len(h.undo)} steps ({h.bytes() / MiB:.0f} MiB estimated), "
          f"{len(runs._runs)} runs ({runs.bytes / MiB:.0f} MiB estimated)")
    body = json.dumps({"params": {"bg_h.junction_points": [[0.1, 0.2]] * 2_000_000}}).encode()
    t = median_s(lambda: check_depth(json.loads(body)), 3)
    print(f"json {len(body) / 1e6:.0f} MB body of 2,000,000 points: json.loads + check_depth median {t:.1f} s "
          f"(on the event loop before a5c829a; now 413 over {1 << 20} bytes, parsed on a thread below it)")


if __name__ == "__main__":
    main()
