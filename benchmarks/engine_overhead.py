"""Engine overhead per node on a graph of trivial nodes.

    python benchmarks/engine_overhead.py [--nodes 1000] [--repeats 7]

Each node adds a constant to a (1, 1) float32 array, so the time measured is the
engine's: validation, keys, planning, scheduling, output checks, caching and
events. Node i reads node i-1 and, for most nodes, a random earlier node too, and
the graph's one output is the last node, so a cold run computes every node.

Rows (medians over the repeats, each cold row with a fresh Session):
  build           GraphBuilder.build(): validation of the whole graph
  cold plan+run   plan() and run() with empty caches: every node computes
  warm, no change plan() and run() again: the output is a memory hit
  warm, 1 param   one param changed at the middle node: half the graph reruns
  warm, last      one param changed at the last node: one node reruns
"""
from __future__ import annotations

import argparse
import os
import platform
import random
import statistics
import sys
import time

import numpy as np

from pixgraph import types as T
from pixgraph.node import node, param, port


class Array(T.PortType):
    """float32 (H, W) array (the benchmark's own port type, so it runs on any
    engine version: domain types moved to the node pack)."""

    @classmethod
    def validate(cls, value):
        if not isinstance(value, np.ndarray) or value.dtype != np.float32:
            raise TypeError("Array must be a float32 numpy array")
from pixgraph.registry import Registry
from pixgraph.session import Session


@node("bench.Inc", version=1)
class Inc:
    """a (+ b) + k on (1, 1) arrays."""

    class Inputs:
        a: Array = port(optional=True)
        b: Array = port(optional=True)

    class Params:
        k: float = param(1.0, min=-1e6, max=1e6)

    class Outputs:
        out: Array = port()

    def compute(self, ctx, inputs, params):
        a = inputs.a if inputs.a is not None else np.zeros((1, 1), np.float32)
        b = inputs.b if inputs.b is not None else 0.0
        return {"out": (a + b + np.float32(params.k)).astype(np.float32)}


def build(session: Session, n: int, seed: int = 0):
    rng = random.Random(seed)
    b = session.builder()
    for i in range(n):
        b.add("bench.Inc", f"n{i}", k=float(i % 7))
        if i:
            b.connect(f"n{i - 1}.out", f"n{i}.a")
            if i > 2 and rng.random() < 0.8:
                b.connect(f"n{rng.randrange(i - 1)}.out", f"n{i}.b")
    b.output("final", f"n{n - 1}.out")
    return b


def cpu_name() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nodes", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    n = args.nodes
    reg = Registry()
    reg.add(Inc, source="benchmark")
    rows: dict[str, list[float]] = {k: [] for k in
                                    ("build", "cold plan+run", "warm, no change", "warm, 1 param (mid)",
                                     "warm, 1 param (last)")}
    reran = {}
    for r in range(args.repeats):
        s = Session(registry=reg, cache_bytes=1 << 30)
        t0 = time.perf_counter()
        g = build(s, n).build()
        rows["build"].append(time.perf_counter() - t0)

        t0 = time.perf_counter()
        s.run(g)
        rows["cold plan+run"].append(time.perf_counter() - t0)
        assert len(s.last_run.ran) == n

        t0 = time.perf_counter()
        s.run(g)
        rows["warm, no change"].append(time.perf_counter() - t0)

        for label, nid in (("warm, 1 param (mid)", f"n{n // 2}"), ("warm, 1 param (last)", f"n{n - 1}")):
            params = {f"{nid}.k": 100.0 + r}
            g2 = s.graph(g, params)  # the edited graph (validation timed in 'build')
            t0 = time.perf_counter()
            s.run(g2)
            rows[label].append(time.perf_counter() - t0)
            reran[label] = len(s.last_run.ran)
    print(f"machine: {cpu_name()}, {os.cpu_count()} CPUs, {platform.platform()}, Python {sys.version.split()[0]}")
    print(f"graph: {n} nodes of bench.Inc, median of {args.repeats} runs\n")
    print(f"{'':24}{'total ms':>10}{'nodes run':>11}{'ms / node':>11}")
    for label, times in rows.items():
        med = statistics.median(times) * 1000
        ran = {"build": n, "cold plan+run": n, "warm, no change": 0}.get(label, reran.get(label))
        per = med / n  # per node of the graph: what the engine pays to look at each node
        print(f"{label:24}{med:10.2f}{ran:11d}{per:11.4f}")
    print("\nms / node = total / graph size (all rows divide by the same node count).")


if __name__ == "__main__":
    main()
