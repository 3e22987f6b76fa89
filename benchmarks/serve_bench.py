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

    python benchmarks/serve_bench.py --photo 5120x3840 [--photo-steps 6] [--browser]

A photo of that size (photo_files: made from the repo's own assets in a temporary
folder, never kept) opened as the page opens it: uploaded with an RGB cutout and
a mask file, the own-photo graph built from the template (POST /api/open), then:
  open -> first final      POST /api/open until the first final PNG has arrived
  drag -> preview (work 1/s) one light-drag step: the whole graph at working
                           resolution 1/s (--scales, default 2 and 5), PNG
  drag -> preview (the page) the same as the page asks while the pointer moves:
                           at most 0.5 MP of work, JPEG
  first step               each working resolution's first step, alone: the photo
                           is read and shrunk to that resolution then (the page's
                           first drag after opening); the drag rows are the rest
  --browser                the same drag in headless Chromium on the page: from the
                           pointer event (the preview is sent in its handler) to
                           the next frame painted after the image was drawn
CPU: the server process's user+sys seconds per drag step (median), next to wall.
Goal from issue 22: light drag -> preview image in the page <= 150 ms at 20 MP.
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
sys.path.insert(0, os.path.join(REPO, "tests"))
from serve_helpers import CHROMIUM_ARGS  # noqa: E402 (how the browser tests start chromium)

METHODS = {"hard": "pixgraph.HardShadow", "classical soft": "pixgraph.SoftShadow",
           "SSN++": "pixgraph.SoftShadowSSN"}


def photo_files(dest: str, width: int = 5120, height: int = 3840, mask: bool = True) -> dict[str, str]:
    """A photo-like ``width`` x ``height`` JPEG and a cutout scaled to it, made from the
    repo's own assets (graphs/assets/own_photo.jpg and own_cutout.png, which our
    renderers made): the photo upsampled (Lanczos) with fine multi-octave grain so it
    is not flat at full size; the cutout as RGB + a mask PNG (``mask``) or RGBA.
    Returns ``{"photo", "cutout"[, "mask"]}`` paths in ``dest``."""
    import numpy as np
    from PIL import Image

    assets = os.path.join(REPO, "graphs", "assets")
    os.makedirs(dest, exist_ok=True)
    photo = Image.open(os.path.join(assets, "own_photo.jpg")).convert("RGB").resize((width, height), Image.LANCZOS)
    rng = np.random.default_rng(22)
    grain = np.zeros((height, width), np.float32)
    for cell, amp in ((1, 2.5), (4, 2.5), (24, 4.0)):       # px per random value, grey levels
        small = rng.normal(0.0, amp, (height // cell + 1, width // cell + 1)).astype(np.float32)
        smooth = Image.fromarray(small, "F").resize((small.shape[1] * cell, small.shape[0] * cell), Image.BICUBIC)
        grain += np.asarray(smooth, np.float32)[:height, :width]
    arr = np.asarray(photo, np.float32) + grain[:, :, None]
    out = {"photo": os.path.join(dest, f"photo_{width}x{height}.jpg")}
    Image.fromarray(np.clip(arr, 0, 255).astype(np.uint8)).save(out["photo"], quality=90)
    cut = Image.open(os.path.join(assets, "own_cutout.png")).convert("RGBA")
    k = height / 480.0
    cut = cut.resize((round(cut.width * k), round(cut.height * k)), Image.LANCZOS)
    if mask:
        out["cutout"] = os.path.join(dest, "figure_rgb.png")
        out["mask"] = os.path.join(dest, "figure_mask.png")
        cut.convert("RGB").save(out["cutout"])
        cut.getchannel("A").save(out["mask"])
    else:
        out["cutout"] = os.path.join(dest, "figure_rgba.png")
        cut.save(out["cutout"])
    return out


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


def _say_error(response: httpx.Response) -> None:
    """An error answer raised with the server's own words (its JSON names the node and
    field), not only its status: a run failing once in many is then explained."""
    if response.is_error:
        response.read()
        raise httpx.HTTPStatusError(f"{response.request.method} {response.request.url.path}: "
                                    f"{response.status_code} {response.text[:1000]}",
                                    request=response.request, response=response)


SAY_ERRORS = {"response": [_say_error]}


def drag(url: str, steps: int, method: str, offset: float) -> tuple[list[float], list[float], float]:
    """Preview latencies over one drag (at the client, and inside the server's
    handler), then the final render's latency."""
    # TCP_NODELAY as browsers set it: httpx writes a POST's headers and body separately,
    # and without it the body waits for the server's delayed ACK (~40 ms)
    nodelay = httpx.HTTPTransport(socket_options=[(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)])
    with httpx.Client(base_url=url, timeout=300, transport=nodelay, event_hooks=SAY_ERRORS) as c:
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

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        page = b.new_page(viewport={"width": 1180, "height": 660})
        page.goto(url + "/")
        page.wait_for_selector("body[data-ready='1']", timeout=120000)
        prev, finals = [], []
        for k in range(3):
            n0 = page.evaluate("window.pixgraphShown.length")
            box = page.locator("#light-handle").bounding_box()
            view = page.locator("#view").bounding_box()
            # image pixels -> page: through the page's view transform (fit and zoom) when it has one
            to_page = page.evaluate("window.pixgraphView ? [window.pixgraphView.state.k,"
                                    " window.pixgraphView.state.ox, window.pixgraphView.state.oy] : [1, 0, 0]")
            page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
            page.mouse.down()
            for tip in tips(steps, 0.05 * k):
                page.mouse.move(view["x"] + to_page[1] + to_page[0] * tip[0], view["y"] + to_page[2] + to_page[0] * tip[1])
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


def start_photo(width: int, height: int, folder: str):
    """A server on a copy of graphs/own_photo.yaml with the limits a photo this size
    needs; then the generated photo, cutout and mask opened as the page opens them."""
    import shutil

    os.makedirs(os.path.join(folder, "served", "assets"), exist_ok=True)
    for name in ("own_photo.jpg", "own_cutout.png"):
        shutil.copy(os.path.join(REPO, "graphs", "assets", name), os.path.join(folder, "served", "assets", name))
    graph = os.path.join(folder, "served", "own_photo.yaml")
    shutil.copy(os.path.join(REPO, "graphs", "own_photo.yaml"), graph)
    files = photo_files(os.path.join(folder, "mine"), width, height, mask=True)
    env = dict(os.environ, OMP_NUM_THREADS="1", PYTHONUNBUFFERED="1")
    proc = subprocess.Popen([sys.executable, "-m", "pixgraph", "serve", graph, "--port", "0", "--no-token",
                             "--max-pixels", str(max(16777216, 2 * width * height)), "--max-body", str(512 << 20)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    line = proc.stdout.readline()
    if "http://" not in line:
        proc.kill()
        raise SystemExit(f"pixgraph serve did not start: {line!r} {proc.stderr.read()[-2000:]}")
    return proc, line.split(" at ", 1)[1].strip().rstrip("/"), files


def cpu_seconds(pid: int) -> float:
    """user + sys CPU seconds of a process so far (its threads included), from /proc."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def photo_drags(url: str, files: dict, width: int, height: int, steps: int, scales, pid: int,
                method: str | None = None) -> list:
    """Rows for the opened photo: open -> first final, and drag -> preview per scale;
    with the server's CPU seconds per step (process ``pid``). ``method``: the cutout
    height's (node fg_h of graphs/own_photo.yaml), set with the open."""
    nodelay = httpx.HTTPTransport(socket_options=[(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)])
    rows = []
    with httpx.Client(base_url=url, timeout=900, transport=nodelay, event_hooks=SAY_ERRORS) as c:
        paths = {}
        for role, path in files.items():
            with open(path, "rb") as f:
                r = c.put(f"/api/uploads/{os.path.basename(path)}", content=f.read())
            r.raise_for_status()
            paths[role] = r.json()["path"]
        t0 = time.perf_counter()
        c.post("/api/open", json=paths).raise_for_status()
        if method:
            c.post("/api/params", json={"params": {"fg_h": {"method": method}}}).raise_for_status()
        c.post("/api/render", json={"mode": "final", "scale": max(scales)}).raise_for_status()
        rows.append((f"open -> first final (height: {method or 'as the graph says'})",
                     [time.perf_counter() - t0], "1 open"))
        foot = c.get("/api/scene").json()["place"]["foot"]
        seq = 0
        # as the page asks while the pointer moves: <= 0.5 MP of work, JPEG (render.js PREVIEW_PIXELS)
        page_work = min(0.5, math.sqrt(0.5e6 / (width * height)))
        cases = [(1 / s, "png", f"work 1/{s}, PNG") for s in scales] + [(page_work, "jpeg",
                                                                          f"work {page_work:.3f}, JPEG: the page")]
        for k, (work, fmt, label) in enumerate(cases):
            times, inside, cpu = [], [], []
            for i in range(steps):   # a new tip each step and each scale: nothing from the cache
                a = math.pi * (0.1 + 0.8 * i / max(1, steps - 1) + 0.03 * k)
                tip = [round(foot[0] + 0.3 * width * math.cos(a), 1), round(foot[1] + 0.04 * height * math.sin(a), 1)]
                seq += 1
                c0 = cpu_seconds(pid)
                t0 = time.perf_counter()
                # the whole graph at working resolution `work`, the image not downscaled again
                r = c.post("/api/render", json={"light_tip": tip, "mode": "preview", "scale": 1, "work": work,
                                                "format": fmt, "client": "bench-photo", "seq": seq})
                r.raise_for_status()
                times.append(time.perf_counter() - t0)
                cpu.append(cpu_seconds(pid) - c0)
                inside.append(float(r.headers["x-pixgraph-seconds"]))
            # the first step is the first render at this working resolution: the photo is read
            # and shrunk to it then (the page's first drag after opening)
            rows.append((f"{width}x{height}: first step ({label}; the photo read at it)", times[:1], "1 step"))
            rows.append((f"{width}x{height}: drag -> preview ({label})", times[1:], f"{steps - 1} steps"))
            rows.append(("  of which inside the server's handler", inside[1:], f"{steps - 1} steps"))
            rows.append(("  server CPU (user+sys) per step", cpu[1:], f"{steps - 1} steps"))
    return rows


def photo_browser(url: str, steps: int) -> list[float]:
    """Preview latencies drawn by the page (the photo is already open on the server)."""
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_ARGS)
        page = b.new_page(viewport={"width": 1280, "height": 800})
        page.goto(url + "/")
        page.wait_for_selector("body[data-ready='1']", state="attached", timeout=900000)
        n0 = page.evaluate("window.pixgraphShown.length")
        box = page.locator("#light-handle").bounding_box()
        stage = page.locator("#stage").bounding_box()
        x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
        page.mouse.move(x, y)
        page.mouse.down()
        for i in range(steps):
            page.mouse.move(x - 15 * (i + 1), min(stage["y"] + stage["height"] - 20, y + 4 * (i + 1)))
            page.wait_for_function(f"window.pixgraphShown.length > {n0 + i}", timeout=900000)
        page.mouse.up()
        # every image painted (a page from before painted_ms has no `kind`: it reports ms only)
        page.wait_for_function(f"window.pixgraphShown.slice({n0}).every(s => s.painted_ms !== undefined"
                               " || !('kind' in s))", timeout=60000)
        shown = page.evaluate(f"window.pixgraphShown.slice({n0})")
        b.close()
        if os.environ.get("PIXGRAPH_BENCH_VERBOSE"):
            for s in shown:
                print(f"  {s['mode']} {s['width']}x{s['height']}: {s.get('painted_ms', s['ms'])} ms painted, "
                      f"{s['server_ms']:.0f} ms in the server; ran {s.get('ran')}", flush=True)
        # from the pointer event (the request is sent in its handler) to the frame painted with the image
        return [s.get("painted_ms", s["ms"]) / 1000 for s in shown
                if s["mode"] == "preview" and s.get("kind", "move") == "move"]


def ms(xs) -> str:
    return f"{1000 * statistics.median(xs):8.1f} ms" if xs else "       -"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--graph", default=os.path.join(REPO, "graphs", "wall_corner_shadow.yaml"))
    ap.add_argument("--steps", type=int, default=25, help="drag steps per method")
    ap.add_argument("--drags", type=int, default=5, help="drags per shadow method")
    ap.add_argument("--starts", type=int, default=3, help="cold starts")
    ap.add_argument("--browser", action="store_true", help="also drag in headless Chromium")
    ap.add_argument("--photo", metavar="WxH", help="instead: open a generated photo of this size (e.g. 5120x3840)")
    ap.add_argument("--photo-steps", type=int, default=6, help="drag steps per scale on the photo")
    ap.add_argument("--scales", default="2,5", help="preview downscales to measure on the photo")
    ap.add_argument("--height", default=None, choices=("contact_line", "column_bottom", "learned", "auto"),
                    help="the photo's cutout height method (graphs/own_photo.yaml's fg_h; default: its own)")
    args = ap.parse_args()

    if args.photo:
        import tempfile

        width, height = (int(x) for x in args.photo.lower().split("x"))
        print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}; photo {width}x{height} "
              f"({width * height / 1e6:.1f} MP), own-photo template, RGB cutout + mask")
        with tempfile.TemporaryDirectory(prefix="pixgraph-bench-") as d:
            proc, url, files = start_photo(width, height, d)
            try:
                rows = photo_drags(url, files, width, height, args.photo_steps,
                                   [int(x) for x in args.scales.split(",")], proc.pid, args.height)
                if args.browser:
                    prev = photo_browser(url, args.photo_steps)
                    rows.append((f"browser: pointer -> preview painted ({width}x{height})", prev,
                                 f"{len(prev)} images"))
                print(f"load average after: {os.getloadavg()[0]:.2f}")
            finally:
                stop(proc)
        for name, xs, n in rows:
            print(f"{name.ljust(52)}  {ms(xs)}  (median of {n})")
        return

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
