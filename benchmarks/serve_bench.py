"""Latency of ``pixgraph serve``: a light drag to the updated image, and cold start.

    python benchmarks/serve_bench.py [--graph graphs/wall_corner_shadow.yaml] [--steps 25]
                                     [--starts 3] [--browser]

Rows (medians; the served graph is 512x512):
  cold start -> listening   spawn ``pixgraph serve`` until it prints its URL
  cold start -> first image spawn until the first final PNG arrives (all nodes run,
                            kernels built or read from PoCL's cache)
  drag -> preview           one drag step: POST /api/render {light_tip, mode: preview}
                            until its PNG has arrived (Light, HardShadow and Composite
                            rerun; 256x256 PNG), --steps per drag, --drags per method;
                            and the part of it inside the server's request handler
  pointer up -> final       the final render at the last drag position, per shadow
                            method (the light is already cached from the preview)
  --browser                 the same drag in headless Chromium: the page's own time
                            from sending each render to drawing its image

Each drag step moves the shadow tip to a new point, so nothing is served from the
cache. Goals from issue 13: preview <= 100 ms, final soft shadow <= 1 s.
"""
from __future__ import annotations

import argparse
import math
import os
import socket
import statistics
import subprocess
import sys
import time

import httpx

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import cpu_model  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
METHODS = {"hard": "pixgraph.HardShadow", "classical soft": "pixgraph.SoftShadow",
           "SSN++": "pixgraph.SoftShadowSSN"}


def start(graph: str):
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "pixgraph", "serve", graph, "--port", "0", "--no-token"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    line = proc.stdout.readline()
    if "http://" not in line:
        proc.kill()
        raise SystemExit(f"pixgraph serve did not start: {line!r} {proc.stderr.read()[-2000:]}")
    return proc, line.split(" at ", 1)[1].strip().rstrip("/"), time.perf_counter() - t0, t0


def stop(proc) -> None:
    proc.terminate()
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()


def tips(n: int, offset: float = 0.0):
    """n shadow-tip positions on an arc over the floor in front of the figure."""
    for i in range(n):
        a = math.pi * (0.15 + 0.7 * i / max(1, n - 1)) + offset
        yield [round(256 + 170 * math.cos(a), 1), round(470 + 25 * math.sin(a), 1)]


def cold_starts(graph: str, n: int) -> tuple[list[float], list[float]]:
    listening, first = [], []
    for _ in range(n):
        proc, url, t_listen, t0 = start(graph)
        try:
            r = httpx.post(url + "/api/render", json={"mode": "final"}, timeout=300)
            r.raise_for_status()
            first.append(time.perf_counter() - t0)
            listening.append(t_listen)
        finally:
            stop(proc)
    return listening, first


def drag(url: str, steps: int, method: str, offset: float) -> tuple[list[float], list[float], float]:
    """Preview latencies over one drag (at the client, and inside the server's
    handler), then the final render's latency."""
    # TCP_NODELAY as browsers set it: httpx writes a POST's headers and body separately,
    # and without it the body waits for the server's delayed ACK (~40 ms)
    nodelay = httpx.HTTPTransport(socket_options=[(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)])
    with httpx.Client(base_url=url, timeout=300, transport=nodelay) as c:
        c.post("/api/params", json={"types": {"shadow": METHODS[method]}}).raise_for_status()
        c.post("/api/render", json={"mode": "final"}).raise_for_status()      # warm: nothing upstream runs
        seq, times, server, last = 0, [], [], None
        for tip in tips(steps, offset):
            seq += 1
            t0 = time.perf_counter()
            r = c.post("/api/render", json={"light_tip": tip, "mode": "preview", "client": f"bench-{offset}", "seq": seq})
            r.raise_for_status()
            times.append(time.perf_counter() - t0)
            server.append(float(r.headers["x-pixgraph-seconds"]))
            last = tip
        seq += 1
        t0 = time.perf_counter()
        c.post("/api/render", json={"light_tip": last, "mode": "final", "client": f"bench-{offset}", "seq": seq}).raise_for_status()
        return times, server, time.perf_counter() - t0


def browser_drag(url: str, steps: int) -> tuple[list[float], list[float]]:
    from playwright.sync_api import sync_playwright

    args = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
            "--disable-background-networking", "--disable-component-update", "--disable-sync"]
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path="/usr/bin/chromium", args=args)
        page = b.new_page(viewport={"width": 1180, "height": 660})
        page.goto(url + "/")
        page.wait_for_selector("body[data-ready='1']", timeout=120000)
        prev, finals = [], []
        for k in range(3):
            n0 = page.evaluate("window.pixgraphShown.length")
            box = page.locator("#light-handle").bounding_box()
            view = page.locator("#view").bounding_box()
            page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
            page.mouse.down()
            for tip in tips(steps, 0.05 * k):
                page.mouse.move(view["x"] + tip[0], view["y"] + tip[1])
                page.wait_for_timeout(30)   # pointer events about as fast as a hand moves
            page.mouse.up()
            page.wait_for_function(f"window.pixgraphShown.length > {n0} && "
                                   "window.pixgraphShown.at(-1).mode === 'final' && "
                                   "document.body.dataset.synced == window.pixgraphShown.at(-1).seq",
                                   timeout=120000)
            shown = page.evaluate(f"window.pixgraphShown.slice({n0})")
            prev += [s["ms"] / 1000 for s in shown if s["mode"] == "preview"]
            finals += [s["ms"] / 1000 for s in shown if s["mode"] == "final"]
        b.close()
        return prev, finals


def ms(xs) -> str:
    return f"{1000 * statistics.median(xs):8.1f} ms" if xs else "       -"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--graph", default=os.path.join(REPO, "graphs", "wall_corner_shadow.yaml"))
    ap.add_argument("--steps", type=int, default=25, help="drag steps per method")
    ap.add_argument("--drags", type=int, default=5, help="drags per shadow method")
    ap.add_argument("--starts", type=int, default=3, help="cold starts")
    ap.add_argument("--browser", action="store_true", help="also drag in headless Chromium")
    args = ap.parse_args()

    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}; graph {os.path.relpath(args.graph)}")
    listening, first = cold_starts(args.graph, args.starts)
    rows = [("cold start -> listening", listening, f"{len(listening)} starts"),
            ("cold start -> first image", first, f"{len(first)} starts")]
    proc, url, _, _ = start(args.graph)
    try:
        for i, method in enumerate(METHODS):
            previews, inside, finals = [], [], []
            for k in range(args.drags):
                p, q, f = drag(url, args.steps, method, 0.01 * (i * args.drags + k))
                previews += p
                inside += q
                finals.append(f)
            rows.append((f"drag -> preview ({method} final)", previews, f"{len(previews)} steps"))
            rows.append(("  of which inside the server's handler", inside, f"{len(inside)} steps"))
            rows.append((f"pointer up -> final, {method}", finals, f"{len(finals)} drags"))
        if args.browser:
            with httpx.Client(base_url=url) as c:
                c.post("/api/params", json={"types": {"shadow": METHODS["classical soft"]}}).raise_for_status()
            prev, finals = browser_drag(url, args.steps)
            rows.append(("browser: drag -> preview drawn", prev, f"{len(prev)} images"))
            rows.append(("browser: pointer up -> final drawn (classical soft)", finals, f"{len(finals)} images"))
    finally:
        stop(proc)
    for name, xs, n in rows:
        print(f"{name.ljust(52)}  {ms(xs)}  (median of {n})")


if __name__ == "__main__":
    main()
