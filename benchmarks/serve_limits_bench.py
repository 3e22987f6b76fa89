"""The server's bounds, measured (issue 23's server goals and issue 21's drag):

    python benchmarks/serve_limits_bench.py [--memory] [--stop N] [--drag-trace] [--side 4096]

--memory      peak RSS growth of the server process (VmHWM, reset between phases)
              while it answers 1, then 50 concurrent GETs of the PNG of a --side^2
              RGBA noise image (a PNG that does not compress); goal: 50 <= 2 x 1.
--stop N      N times: start a render of the wall-corner graph with 65536 light
              samples (minutes of work), wait until it runs, send SIGTERM (then
              SIGINT), time until the process has exited; goal <= 1 s. Then the
              same with no render going (after one run).
--drag-trace  one light-drag step (POST /api/render {light_tip}) in-process, traced:
              graph runs, first-party files it enters and file-to-file calls. Run it
              also with BEFORE=path to an older checkout's package folder (holding
              pixgraph/, pixgraph_serve/ or pixgraph/serve/, pixgraph_nodes/) to
              compare: ``BEFORE=/tmp/before python benchmarks/serve_limits_bench.py --drag-trace``,
              the folder made by e.g. ``git archive main pixgraph nodes | tar -x -C /tmp/src;
              git archive ac8343f pixgraph_serve | tar -x -C /tmp/src`` and links
              /tmp/before/{pixgraph,pixgraph_serve,pixgraph_nodes} to /tmp/src/{pixgraph,pixgraph_serve,nodes}.
"""
from __future__ import annotations

import argparse
import asyncio
import os
import signal
import statistics
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "tests"))
if os.environ.get("BEFORE"):
    sys.path.insert(0, os.environ["BEFORE"])

from _machine import cpu_model  # noqa: E402


def memory(side: int) -> None:
    import numpy as np
    from PIL import Image

    from serve_helpers import start_server
    from test_serve_memory import GRAPH, measure

    with tempfile.TemporaryDirectory() as d:
        rng = np.random.default_rng(0)
        for name in ("a.png", "b.png"):
            Image.fromarray(rng.integers(0, 256, (side, side, 4), dtype=np.uint8), "RGBA").save(os.path.join(d, name))
        with open(os.path.join(d, "g.yaml"), "w") as f:
            f.write(GRAPH)
        env = {"MALLOC_MMAP_THRESHOLD_": str(128 << 10), "MALLOC_ARENA_MAX": "2"}
        with start_server(os.path.join(d, "g.yaml"), "--no-token", "--max-body", str(1 << 30),
                          env=env) as (url, _, proc):
            t0 = time.perf_counter()
            one, size = measure(url, proc.pid, 1, "a.png")
            t1 = time.perf_counter()
            fifty, _ = measure(url, proc.pid, 50, "b.png")
            t2 = time.perf_counter()
    print(f"{side}x{side} RGBA noise, PNG {size / 2**20:.1f} MiB")
    print(f"peak RSS growth, 1 GET                        {one / 2**20:8.1f} MiB  (run + GET {t1 - t0:.1f} s)")
    print(f"peak RSS growth, 50 concurrent GETs           {fifty / 2**20:8.1f} MiB  (run + GETs {t2 - t1:.1f} s)")
    print(f"ratio (goal <= 2)                             {fifty / one:8.2f}")


def stop(n: int) -> None:
    import httpx

    from serve_helpers import copy_scene, start_server

    for sig in (signal.SIGTERM, signal.SIGINT):
        times = []
        for _ in range(n):
            with tempfile.TemporaryDirectory() as d:
                graph = copy_scene(os.path.join(d, "scene"))
                with start_server(graph, "--no-token") as (url, _, proc):
                    async def main():
                        async with httpx.AsyncClient(base_url=url, timeout=600) as c:
                            long = asyncio.create_task(c.post("/api/render",
                                                              json={"params": {"shadow.samples": 65536}}))
                            while not (await c.get("/api/status")).json()["running"]:
                                await asyncio.sleep(0.005)
                            await asyncio.sleep(0.3)      # well inside the render (it runs for minutes)
                            t0 = time.perf_counter()
                            proc.send_signal(sig)
                            code = await asyncio.get_running_loop().run_in_executor(None, proc.wait, 30)
                            long.cancel()
                            return code, time.perf_counter() - t0

                    code, seconds = asyncio.run(main())
                    assert code == 0, code
                    times.append(seconds)
        print(f"{signal.Signals(sig).name} mid-render -> exited     median {statistics.median(times) * 1000:7.1f} ms"
              f"  max {max(times) * 1000:7.1f} ms  (of {n}; goal <= 1000 ms)")
    idle = []
    for _ in range(n):
        with tempfile.TemporaryDirectory() as d:
            with start_server(copy_scene(os.path.join(d, "scene")), "--no-token") as (url, _, proc):
                httpx.post(url + "/api/run", json={}, timeout=300).raise_for_status()
                t0 = time.perf_counter()
                proc.send_signal(signal.SIGTERM)
                assert proc.wait(30) == 0
                idle.append(time.perf_counter() - t0)
    print(f"SIGTERM idle -> exited           median {statistics.median(idle) * 1000:7.1f} ms"
          f"  max {max(idle) * 1000:7.1f} ms  (of {n})")


def drag_trace(steps: int = 30) -> None:
    import inspect
    import threading

    from starlette.testclient import TestClient

    from serve_helpers import copy_scene

    try:
        from pixgraph_serve import app as app_mod
        from pixgraph_serve.state import ServeState
    except ImportError:                                   # before the move: pixgraph/serve
        from pixgraph.serve import app as app_mod
        from pixgraph.serve.state import ServeState
    import pixgraph
    import pixgraph_nodes

    roots = [os.path.dirname(pixgraph.__file__), os.path.dirname(app_mod.__file__),
             os.path.dirname(pixgraph_nodes.__file__)]
    print("code from:", ", ".join(sorted(set(roots))))
    d = tempfile.mkdtemp()
    state = ServeState(copy_scene(os.path.join(d, "scene")))
    kw = {"port": 8999} if "port" in inspect.signature(app_mod.create_app).parameters else {}
    client = TestClient(app_mod.create_app(state, **kw), base_url="http://127.0.0.1:8999")
    runs = []
    real_run = state.session.run
    state.session.run = lambda *a, **k: (runs.append(1), real_run(*a, **k))[1]

    def step(i):
        r = client.post("/api/render", json={"light_tip": [150 + i, 420 - i], "mode": "preview",
                                             "client": "trace", "seq": i})
        assert r.status_code == 200, r.text

    with client:
        for i in range(3):
            step(i)                                       # warm: caches, kernels
        times = []
        for i in range(20, 20 + steps):
            t0 = time.perf_counter()
            step(i)
            times.append(time.perf_counter() - t0)
    print(f"drag step in-process (preview, 512^2): median {statistics.median(times) * 1000:.1f} ms of {steps}")
    files, crossings = set(), [0]
    if True:

        def prof(frame, event, arg):
            if event != "call":
                return
            f = frame.f_code.co_filename
            if not any(f.startswith(r) for r in roots):
                return
            files.add(os.path.relpath(f, os.path.dirname(roots[0])))
            back = frame.f_back
            while back is not None and not any(back.f_code.co_filename.startswith(r) for r in roots):
                back = back.f_back
            if back is not None and back.f_code.co_filename != f:
                crossings[0] += 1

        runs.clear()
        threading.setprofile(prof)       # the new client's event loop and worker threads start after this
        sys.setprofile(prof)
        try:
            with client:
                step(100)
        finally:
            sys.setprofile(None)
            threading.setprofile(None)
    print(f"one drag step: {len(runs)} graph run(s), {len(files)} first-party files entered, "
          f"{crossings[0]} calls from one first-party file into another")
    for f in sorted(files):
        print("   ", f)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--memory", action="store_true")
    ap.add_argument("--side", type=int, default=4096)
    ap.add_argument("--stop", type=int, default=0, metavar="N")
    ap.add_argument("--drag-trace", action="store_true")
    args = ap.parse_args()
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}")
    if args.memory:
        memory(args.side)
    if args.stop:
        stop(args.stop)
    if args.drag_trace:
        drag_trace()


if __name__ == "__main__":
    main()
