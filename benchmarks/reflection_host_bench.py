"""Host work of the glossy Reflection node on the photo benchmark's scene (issue 24):
the node's ``compute`` timed in one process on the inputs of ``photo_bench.py --case
glossy``, split into the trace (``reflection_cl`` at the proxy, on the device) and
everything else (the host part: input checks, the proxy scene, the enlargement, the
stats maps).

    python benchmarks/reflection_host_bench.py --size 20mp --repeat 3
    python benchmarks/reflection_host_bench.py --size 20mp --profile   # cProfile of the last run

The upstream nodes run once (not timed); each timed run forgets the input checks'
memory of frozen arrays (``_checks._PASSED``), as a fresh process would, after one
untimed run that builds the kernels. Prints medians and the machine's load.
Nothing here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from _machine import NodeContext, cpu_model
from photo_bench import ROOT, SIZES, make_graph


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", default="20mp", choices=tuple(SIZES))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--profile", action="store_true", help="cProfile of the last run (cumulative, nodes only)")
    a = ap.parse_args()
    from pixgraph.node import Namespace
    from pixgraph.registry import Registry
    from pixgraph.session import Session
    from pixgraph_nodes import _checks
    from pixgraph_nodes.ops import reflection_proxy

    s = Session(disk_cache=None, allow_paths=[str(ROOT)])
    g = s.graph(make_graph("glossy", a.size))
    up = s.run(g, outputs=["cam.camera", "place.image", "place.height", "bg_h.height"])
    set_params = dict(g.nodes["refl"].params)
    spec = Registry.discover().get("pixgraph.Reflection")
    params = {p.name: p.default for p in spec.params}
    params.update(set_params)
    inputs = Namespace(dict(camera=up["cam.camera"], cutout=up["place.image"], fg_height=up["place.height"],
                            bg_height=up["bg_h.height"], mask=None, receiver=None))
    device = s.device

    trace = []
    traced = reflection_proxy.reflection_cl

    def timed(*args, **kw):
        t0 = time.perf_counter()
        r = traced(*args, **kw)
        trace.append(time.perf_counter() - t0)
        return r
    reflection_proxy.reflection_cl = timed
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f} at start; "
          f"{SIZES[a.size][0]}x{SIZES[a.size][1]}; params {dict(sorted(set_params.items()))}")
    spec.cls().compute(NodeContext(device), Namespace(dict(inputs)), Namespace(params))     # builds the kernels
    trace.clear()
    total = []
    for k in range(a.repeat):
        _checks._PASSED.clear()
        prof = None
        if a.profile and k == a.repeat - 1:
            import cProfile
            prof = cProfile.Profile()
            prof.enable()
        t0 = time.perf_counter()
        spec.cls().compute(NodeContext(device), Namespace(dict(inputs)), Namespace(params))
        total.append(time.perf_counter() - t0)
        if prof is not None:
            prof.disable()
            import pstats
            pstats.Stats(prof, stream=sys.stderr).sort_stats("cumulative").print_stats("nodes", 30)
    host = [t - x for t, x in zip(total, trace)]
    print(f"Reflection node: median {statistics.median(total):.3f} s (runs {', '.join(f'{t:.3f}' for t in total)}); "
          f"trace {statistics.median(trace):.3f} s; host {statistics.median(host):.3f} s "
          f"(runs {', '.join(f'{t:.3f}' for t in host)}); load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
