"""The numbers behind the server's byte bounds on JSON bodies, undo steps and run
records (docs/server.md, "Undo" and "Errors"; ``pixgraph_serve/history.py``):

    python benchmarks/serve_bytes_bench.py [--nodes 8000] [--points 2000000] [--repeat 5]

- one state of an N-node graph (Constant nodes of 3 params, loaded from YAML as a
  posted graph is, lines included): the bytes it holds (tracemalloc, after a
  collection) and ``history.graph_bytes``'s estimate, and the time of that estimate;
- 20 edits of an N-node graph recorded as the server does (``History`` and ``Runs``,
  each graph distinct, built as ``tests/test_serve_undo_bytes.py``'s ``big_graph``:
  no source lines): steps and runs kept and the bytes they hold (tracemalloc), with
  the byte bounds (64 MiB each) and without them (the count bounds alone, as before);
- a JSON edit of a P-point ``junction_points`` list: its size and the time of
  ``json.loads`` and the depth check, which ran on the event loop before (every
  other client waited that long) and run on a worker thread now.

Times are medians of --repeat runs (min and max beside), on this machine's CPU
(printed, with the load average).
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import statistics
import sys
import time
import tracemalloc

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))

from _machine import cpu_model  # noqa: E402

MiB = 1 << 20


def held(make):
    """``make()``'s result and the bytes it holds after a collection (tracemalloc) [bytes]."""
    gc.collect()
    tracemalloc.start()
    try:
        out = make()
        gc.collect()
        return out, tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()


def timed(fn, repeat: int) -> tuple[float, float, float]:
    """Median, min and max seconds of ``fn()`` over ``repeat`` runs [s]."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), min(times), max(times)


def graph_text(n: int, tag: int) -> str:
    return "pixgraph: 1\nnodes:\n" + "".join(
        f"  c{i}: {{type: pixgraph.Constant, params: {{width: {8 + tag}, height: 8, color: [0.1, 0.2, 0.3, 1]}}}}\n"
        for i in range(n)) + "outputs: {final: c0.image}\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nodes", type=int, default=8000)
    ap.add_argument("--points", type=int, default=2_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--edits", type=int, default=20)
    a = ap.parse_args()

    from pixgraph import fileio
    from pixgraph.registry import Registry
    from pixgraph_serve.app import parse_json
    from pixgraph_serve.history import History, Step, graph_bytes
    from pixgraph_serve.runs import Runs
    from test_serve_undo_bytes import big_graph

    print(f"machine: {cpu_model()}, load average {os.getloadavg()[0]:.2f}")
    reg = Registry.discover()
    fileio.loads(graph_text(10, 0), reg)               # the loader's own caches are no graph's
    graph, size = held(lambda: fileio.loads(graph_text(a.nodes, 0), reg))
    est = graph_bytes(graph)
    t = timed(lambda: graph_bytes(graph), a.repeat)
    print(f"one state of {a.nodes} nodes: holds {size / MiB:.1f} MiB, graph_bytes {est / MiB:.1f} MiB "
          f"(x{est / size:.2f}); graph_bytes takes {t[0] * 1e3:.0f} ms (min {t[1] * 1e3:.0f}, max {t[2] * 1e3:.0f})")

    for label, max_bytes in (("byte bounds (64 MiB)", 64 << 20), ("count bounds alone", 1 << 62)):
        def edits():
            h, runs = History(100, max_bytes), Runs(256, max_bytes)
            now = big_graph(a.nodes, 0)
            for k in range(1, a.edits + 1):
                new = big_graph(a.nodes, k)
                h.record(Step(now, {}), new, None)
                runs.add(new, "final", ["final"])
                now = new
            return h, runs, now
        (h, runs, now), total = held(edits)
        print(f"{a.edits} edits, {label}: {len(h.undo)} steps and {len(runs._runs)} runs kept, "
              f"holding {total / MiB:.0f} MiB with the current graph")
        del h, runs, now

    body = json.dumps({"params": {"bg_h.junction_points": [[0.1, 0.2]] * a.points}}).encode()
    t = timed(lambda: parse_json(body), a.repeat)
    print(f"a JSON edit of {a.points} points, {len(body) / 1e6:.1f} MB: parsed and depth-checked in "
          f"{t[0]:.2f} s (min {t[1]:.2f}, max {t[2]:.2f}); refused unread now (over 1 MiB)")


if __name__ == "__main__":
    main()
