"""SSN++ next to a busy neighbour: idle against loaded, torch's default threads against pixgraph's.

    python benchmarks/ssn_threads_bench.py [--busy 2] [--runs 15] [--threads 1 --threads 2]

Torch and PoCL share the cores with each other and with whatever else runs
(the host application, other workers). This measures the SoftShadowSSN node's
work on the ssn_wall_corner.yaml example scene (512x512): ``network``, the
SSN++ inference alone on the whole image (``ssn.predict``, resize to 256^2 and
back included), and ``node``, what the node runs (``ssn_crop.render``: the
buffer channels of the object's window on the OpenCL device, then the network).

Thread settings compared, side by side in the same rounds:
  torch default  torch's own intra-op thread count (one per core): what
                 SSN++ ran with before pixgraph chose (the "before");
  pixgraph       ``ssn.inference_threads()``: PIXGRAPH_TORCH_THREADS, else
                 its default (the "after");
  N threads      each ``--threads N``.

Two conditions: ``idle`` (nothing of ours running besides this process) and
``loaded``: ``--busy`` processes spinning a pure-Python loop each (a busy
neighbour). The busy processes are started once and paused (SIGSTOP) or resumed
(SIGCONT), so idle and loaded rounds alternate and a change in the machine's
other load hits both alike; within a round the settings take turns. Reports
the median ms of ``--runs`` rounds of each condition after a warm-up, and
loaded/idle. The machine is printed; on a shared machine "idle" carries the
other users' load (the load average is printed).

Nothing here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import signal
import statistics
import subprocess
import sys
import time


from _machine import cpu_model

ROOT = pathlib.Path(__file__).resolve().parents[1]


def scene():
    """The example's inputs of the SSN++ node (512x512) and the model."""
    from pixgraph.session import Session

    s = Session(disk_cache=None)
    v = s.run(ROOT / "graphs" / "ssn_wall_corner.yaml",
              outputs=["cutout.alpha", "fg_h.height", "bg_h.height", "light.light", "cam.camera"])
    return v["cutout.alpha"], v["fg_h.height"], v["bg_h.height"], v["light.light"], v["cam.camera"]


def busy(n: int) -> list[subprocess.Popen]:
    """``n`` processes spinning on a core each, until killed (started paused)."""
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(n)]
    set_busy(procs, False)
    return procs


def set_busy(procs, on: bool) -> None:
    for p in procs:
        p.send_signal(signal.SIGCONT if on else signal.SIGSTOP)
    time.sleep(0.3)   # let the scheduler settle


def measure(cases: dict, runs: int, procs) -> dict[str, dict[str, list[float]]]:
    for fn in cases.values():      # warm-up: thread pools started, caches filled
        fn()
    times = {cond: {name: [] for name in cases} for cond in ("idle", "loaded")}
    for _ in range(runs):
        for cond in ("idle", "loaded"):
            set_busy(procs, cond == "loaded")
            for name, fn in cases.items():
                t = time.perf_counter()
                fn()
                times[cond][name].append((time.perf_counter() - t) * 1e3)
    set_busy(procs, False)
    return times


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--busy", type=int, default=2, help="busy processes in the loaded phase")
    ap.add_argument("--runs", type=int, default=15, help="timed rounds per phase (median)")
    ap.add_argument("--threads", type=int, action="append", default=[], help="also time N torch threads")
    a = ap.parse_args(argv)

    import torch

    from pixgraph.device import Device
    from pixgraph_nodes.ops import ssn, ssn_crop
    from pixgraph_nodes.ops.buffers import buffer_channels
    from pixgraph_nodes.ops.lights import disk_extremes, light_point
    from pixgraph_nodes.ssn_soft_shadow import load_shipped

    default_threads = torch.get_num_threads()
    ours = ssn.inference_threads()
    settings = {f"torch default ({default_threads})": default_threads, f"pixgraph ({ours})": ours}
    settings.update({f"{n} thread{'s' * (n > 1)}": n for n in a.threads})
    print(f"machine: {cpu_model()}, torch {torch.__version__}, "
          f"{len(os.sched_getaffinity(0))} CPUs usable by this process")
    print(f"{ssn.THREADS_ENV}={os.environ.get(ssn.THREADS_ENV, '(unset)')}")
    dev = Device.open()
    print(f"device: {dev.name}")
    mask, fg, bg, light, cam = scene()
    model = load_shipped("ssnpp")
    lp, le = light_point(light, cam), disk_extremes(light, cam)
    softness = ssn.softness_of(light, cam, mask, fg)
    buffers = buffer_channels(dev, mask, fg, bg, lp, le)

    cases = {}
    for label, n in settings.items():
        cases[f"network, {label}"] = lambda n=n: ssn.predict(model, buffers, softness, n)
        cases[f"node, {label}"] = lambda n=n: ssn_crop.render(dev, model, mask, fg, bg, lp, le, softness,
                                                              threads=n)

    print(f"\n{a.busy} busy processes in the loaded rounds; load average before {os.getloadavg()}")
    procs = busy(a.busy)
    try:
        times = measure(cases, a.runs, procs)
    finally:
        for p in procs:
            p.kill()
            p.wait()
    idle, loaded = times["idle"], times["loaded"]
    print(f"load average after {os.getloadavg()}")
    print(f"\n{'512x512, median of ' + str(a.runs):42s} {'idle ms':>9s} {'loaded ms':>10s} {'loaded/idle':>12s}")
    for name in cases:
        i, lo = statistics.median(idle[name]), statistics.median(loaded[name])
        print(f"{name:42s} {i:9.1f} {lo:10.1f} {lo / i:12.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
