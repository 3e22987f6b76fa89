"""How fast a long soft shadow stops: cancellation from another thread and Ctrl-C on the CLI.

    python benchmarks/cancel_bench.py [--runs 5] [--samples 65536]

Scene: graphs/ground_shadow.yaml (512x512) with ``shadow.samples`` set to
``--samples`` (65,536 by default: about a minute of work on a 2-core CPU).

thread  ``Session.run`` with a ``CancelToken``, cancelled from another thread
        0.5 s after the shadow node's first progress event; reported: seconds
        from ``cancel()`` to ``Cancelled`` raised in the caller.
sigint  ``pixgraph run`` as a subprocess, SIGINT 1 s after the shadow's inputs
        appeared in its disk cache (so the shadow is running); reported: seconds
        from the signal to the process's exit (interpreter and OpenCL teardown
        included), its exit code, and whether the shadow left a cache entry.

Medians and maxima over ``--runs``; the machine and its load average are printed.
Nothing here is asserted by the tests (tests/test_node_cancel.py checks the behaviour).
"""
from __future__ import annotations

import argparse
import os
import pathlib
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time

from _machine import cpu_model

ROOT = pathlib.Path(__file__).resolve().parents[1]
GRAPH = ROOT / "graphs" / "ground_shadow.yaml"


def thread_latency(samples: int) -> float:
    from pixgraph.events import CancelToken, Cancelled, NodeProgress
    from pixgraph.session import Session

    s = Session(disk_cache=None)
    g = s.graph(GRAPH, {"shadow.samples": samples})
    token, at, armed = CancelToken(), [], []

    def cancel_later():
        time.sleep(0.5)
        at.append(time.perf_counter())
        token.cancel()

    def on_event(ev):
        if isinstance(ev, NodeProgress) and ev.node_id == "shadow" and not armed:
            armed.append(True)
            threading.Thread(target=cancel_later, daemon=True).start()

    try:
        s.run(g, cancel=token, on_event=on_event)
    except Cancelled:
        return time.perf_counter() - at[0]
    raise RuntimeError("the run finished before it was cancelled")


def sigint_latency(samples: int) -> tuple[float, int, bool]:
    from pixgraph.cache import DiskCache
    from pixgraph.session import Session

    with tempfile.TemporaryDirectory() as d:
        cache = os.path.join(d, "cache")
        plan = Session(disk_cache=cache).plan(GRAPH, params={"shadow.samples": samples})
        need = [plan.keys[n] for n in ("fg_h", "bg_h", "cutout")]
        env = dict(os.environ, PIXGRAPH_DISK_CACHE=cache)
        p = subprocess.Popen([sys.executable, "-m", "pixgraph", "run", str(GRAPH), "-q",
                              "--set", f"shadow.samples={samples}", "-o", f"final={d}/final.png"],
                             env=env, stderr=subprocess.DEVNULL)
        disk = DiskCache(cache, 1 << 30)
        while not all(k in disk for k in need):
            if p.poll() is not None:
                raise RuntimeError("pixgraph exited before the shadow started")
            time.sleep(0.05)
        time.sleep(1.0)
        t = time.perf_counter()
        p.send_signal(signal.SIGINT)
        rc = p.wait()
        return time.perf_counter() - t, rc, plan.keys["shadow"] in disk


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--samples", type=int, default=65536)
    a = ap.parse_args(argv)
    print(f"machine: {cpu_model()}; load average {os.getloadavg()}")
    th = [thread_latency(a.samples) for _ in range(a.runs)]
    sg = [sigint_latency(a.samples) for _ in range(a.runs)]
    lat = [x[0] for x in sg]
    print(f"{a.samples}-sample soft shadow, 512x512, {a.runs} runs each")
    print(f"thread cancel -> Cancelled raised: median {statistics.median(th) * 1e3:.0f} ms, "
          f"max {max(th) * 1e3:.0f} ms")
    print(f"SIGINT -> process exit:            median {statistics.median(lat) * 1e3:.0f} ms, "
          f"max {max(lat) * 1e3:.0f} ms; exit codes {sorted({x[1] for x in sg})}; "
          f"shadow cache entries left: {sum(x[2] for x in sg)}")
    print(f"load average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
