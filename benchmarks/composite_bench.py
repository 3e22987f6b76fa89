"""The final's composite on the photo benchmark's scenes (issue 24): the Composite
(``--case soft``) or ReflectionComposite (``--case glossy``) node's ``compute``
timed in one process on the inputs of ``photo_bench.py``, and its parts: the input
checks (``same_size``, ``finite``), the boxes the shadow and the layers touch
(``_shadow_plan``, ``_over_plan``) and the whole composite on the host (numpy,
``composite_layers``) and on the OpenCL device (``composite_layers_cl``).

    python benchmarks/composite_bench.py --case glossy --size 20mp --repeat 3
    PIXGRAPH_DEVICE=nvidia python benchmarks/composite_bench.py --case soft --case glossy --size 20mp

Each row: the median wall-clock and process CPU seconds (all threads: on a loaded
shared machine the steadier number), and each run's wall-clock. The upstream nodes
run once (not timed). Each timed run forgets the input checks'
and the boxes' memory of frozen arrays (``_checks._PASSED``, ``composite._BOXES``),
as a fresh process would; one untimed run first builds the kernels. Every device
result is compared with the numpy one (max |difference|, printed). The "node" row
is whatever the installed node does (on an older tree without the device path:
numpy), so the script also times a "before" tree laid over this one
(benchmarks/gpu_before_after.sh). Prints medians, the device and the machine's load.
Nothing here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

from _machine import NodeContext, cpu_model
from photo_bench import ROOT, SIZES, make_graph

PORTS = {"soft": dict(background="photo.image", cutout="place.image", alpha="place.alpha", shadow="shadow.darkness"),
         "glossy": dict(background="photo.image", cutout="place.image", alpha="place.alpha", reflection="refl.layer",
                        shadow="shadow.darkness", refraction=None)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", action="append", choices=tuple(PORTS))
    ap.add_argument("--size", default="20mp", choices=tuple(SIZES))
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    from pixgraph.node import Namespace
    from pixgraph.registry import Registry
    from pixgraph.session import Session
    from pixgraph_nodes import _checks
    from pixgraph_nodes.ops import composite as C

    s = Session(disk_cache=None, allow_paths=[str(ROOT)])
    device = s.device
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f} at start; "
          f"{SIZES[a.size][0]}x{SIZES[a.size][1]}; device {device.name}; "
          f"PIXGRAPH_THREADS={os.environ.get('PIXGRAPH_THREADS', '(default)')}")


    def forget():
        _checks._PASSED.clear()
        C._BOXES._items.clear()

    def timed(fn):
        fn()                         # builds the kernels, warms the pool
        runs, cpus = [], []
        for _ in range(a.repeat):
            forget()
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            runs.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0)
        return (f"{statistics.median(runs):.3f} s, cpu {statistics.median(cpus):.3f} s "
                f"(runs {', '.join(f'{t:.3f}' for t in runs)})")
    for case in a.case or ["soft", "glossy"]:
        g = s.graph(make_graph(case, a.size))
        ports = {k: v for k, v in PORTS[case].items() if v}
        up = s.run(g, outputs=sorted(set(ports.values())))
        inputs = {k: (up[v] if v else None) for k, v in PORTS[case].items()}
        spec = Registry.discover().get(g.nodes["comp"].type)
        params = {p.name: p.default for p in spec.params}
        params.update(g.nodes["comp"].params)
        layers = [(inputs["cutout"], inputs["alpha"])]
        if inputs.get("reflection") is not None:
            layers.insert(0, (inputs["reflection"], inputs["reflection"][..., 3]))
        args = (inputs["background"], inputs["shadow"], params["opacity"], params["tint"], layers)
        print(f"== {case} ({g.nodes['comp'].type}), load {os.getloadavg()[0]:.2f}")
        print(f"  node compute:          {timed(lambda: spec.cls().compute(NodeContext(device), Namespace(inputs), Namespace(params)))}")
        print(f"  input checks:          {timed(lambda: (_checks.same_size(**inputs), _checks.finite(**inputs)))}")
        bg = inputs["background"]
        print(f"  boxes (plans):         {timed(lambda: [C._shadow_plan(bg.shape, inputs['shadow'], 0.5, (0, 0, 0))] + [C._over_plan(bg.shape, f, al) for f, al in layers])}")
        print(f"  composite_layers:      {timed(lambda: C.composite_layers(*args))}")
        if hasattr(C, "composite_layers_cl"):
            print(f"  composite_layers_cl:   {timed(lambda: C.composite_layers_cl(device, *args))}")
            diff = np.abs(C.composite_layers_cl(device, *args) - C.composite_layers(*args)).max()
            print(f"  device - numpy: max |difference| {diff:.3g}")
        print(f"  load {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
