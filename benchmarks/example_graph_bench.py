"""The README's job through the command line: wall time of
``pixgraph run graphs/wall_corner_shadow.yaml -o final=out.png --no-disk-cache``,
a fresh process each time (startup, discovery, the graph, the PNG).

    python benchmarks/example_graph_bench.py [--repeats 5]

(This was a wall-clock assert, < 10 s, in tests/test_graphs_examples.py.)
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import cpu_model  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "pixgraph", "run",
                                os.path.join(ROOT, "graphs", "wall_corner_shadow.yaml"),
                                "-o", f"final={os.path.join(tmp, 'out.png')}", "--no-disk-cache", "-q"],
                               capture_output=True, text=True)
            times.append(time.perf_counter() - t0)
            if r.returncode:
                sys.exit(r.stderr)
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.1f}")
    print(f"pixgraph run graphs/wall_corner_shadow.yaml: median {statistics.median(times):.2f} s "
          f"(min {min(times):.2f}, max {max(times):.2f}) over {args.repeats} runs")


if __name__ == "__main__":
    main()
