"""Batch throughput: composites per second for a light sweep at 512^2, and a light sweep on a 20 MP photo.

Four ways of running the same rows (one light azimuth per row) of two graphs,
the classical soft shadow (graphs/ground_shadow.yaml, 48 light samples) and
SSN++ (graphs/ssn_wall_corner.yaml):

- ``inprocess``: ``pixgraph_batch.batch(session)`` in this process (one device, shared cache);
- ``cli-loop``: one ``pixgraph run`` process per row, as a shell loop does
  (measured on the first ``--cli-rows`` rows only: it is the slow baseline);
- ``processes``: ``pixgraph_batch.batch(session, executor="processes", workers=2)``;
- ``dask``: ``pixgraph_batch.batch(session, executor="dask", workers=2)`` on a ``LocalCluster``.

Each run is timed end to end (pool or cluster start included) with a fresh
session and no disk cache, ``--repeats`` times; the table shows medians. It also
prints the median per-row seconds inside the workers and a simulated scale-out:
throughput with N machines of ``--workers-per-machine`` workers, from the
measured per-row cost and the Dask scheduler's per-task overhead (measured with
no-op tasks on the same LocalCluster)::

    T(N) = startup + max(rows * t_row / (N * w), rows * t_sched)   (rows: --sim-rows)

    python benchmarks/batch_bench.py --rows 200            # the full run
    python benchmarks/batch_bench.py --rows 24 --repeats 3 # on a shared 2-core machine

``--photo`` measures instead what issue 22 asks of a batch on a large photo: 6
light positions on a 20-megapixel photo (5120x3840, made here from the repo's
own assets by ``photo_scene``: graphs/own_photo.yaml's photo and cutout scaled
8x with sensor grain added; never committed), as 6 ``pixgraph run`` processes
(a shell loop) and as one ``pixgraph batch`` process, each with no disk cache and
with a fresh disk cache, end to end (process start included)::

    python benchmarks/batch_bench.py --photo --repeats 2
    python benchmarks/batch_bench.py --photo-profile   # where a row's time goes
    python benchmarks/batch_bench.py --png --repeats 3 # PNG writers side by side at 20 MP
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import cpu_model  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GRAPHS = {"classical": "graphs/ground_shadow.yaml", "ssn": "graphs/ssn_wall_corner.yaml"}


def azimuths(rows: int) -> list[float]:
    return [round(-80.0 + 160.0 * i / max(1, rows - 1), 3) for i in range(rows)]


def run_batch(graph: str, rows: int, executor: str, workers: int, out: str):
    import pixgraph_batch
    from pixgraph.session import Session

    s = Session()  # fresh: memory cache empty, no disk cache
    t0 = time.perf_counter()
    res = pixgraph_batch.batch(s, os.path.join(ROOT, graph), [{"light.azimuth": a} for a in azimuths(rows)],
                  outputs={"final": os.path.join(out, "{row}.png")}, executor=executor, workers=workers,
                  force=True)
    wall = time.perf_counter() - t0
    if res.failed:
        raise SystemExit(f"{graph} {executor}: {len(res.failed)} rows failed:\n{res.table()}")
    return wall, [r.seconds for r in res.results]


def run_cli_loop(graph: str, rows: int, out: str) -> float:
    exe = [sys.executable, "-m", "pixgraph"]
    t0 = time.perf_counter()
    for i, a in enumerate(azimuths(rows)):
        subprocess.run(exe + ["run", os.path.join(ROOT, graph), "--no-disk-cache", "-q", "--set",
                              f"light.azimuth={a}", "-o", f"final={out}/{i:04d}.png"], check=True)
    return time.perf_counter() - t0


def scheduler_overhead(tasks: int = 400) -> tuple[float, float]:
    """(LocalCluster start seconds, seconds per no-op task through the scheduler, 2 workers)."""
    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    client.submit(int, 0, pure=False).result()
    start = time.perf_counter() - t0
    try:
        per = []
        for _ in range(3):
            t0 = time.perf_counter()
            client.gather(client.map(int, range(tasks), pure=False))
            per.append((time.perf_counter() - t0) / tasks)
        return start, statistics.median(per)
    finally:
        client.close()
        cluster.close()


def photo_scene(folder: str, width: int = 5120, height: int = 3840) -> str:
    """A photo-like scene at ``width`` x ``height`` in ``folder`` (photo.jpg, cutout.png,
    g.yaml): graphs/own_photo.yaml with its assets scaled by ``width / 640`` (bicubic,
    plus sensor grain so the photo compresses like one) and its pixel params scaled
    to match. Returns the graph file."""
    import numpy as np
    from PIL import Image

    k = width / 640
    photo = Image.open(os.path.join(ROOT, "graphs/assets/own_photo.jpg")).convert("RGB")
    a = np.asarray(photo.resize((width, height), Image.BICUBIC), np.float32)
    a += np.random.default_rng(0).normal(0, 4.0, a.shape[:2] + (1,)).astype(np.float32)
    Image.fromarray(np.clip(a, 0, 255).astype(np.uint8)).save(os.path.join(folder, "photo.jpg"), quality=92)
    cut = Image.open(os.path.join(ROOT, "graphs/assets/own_cutout.png"))
    cut.resize((round(cut.width * k), round(cut.height * k)), Image.BICUBIC).save(os.path.join(folder, "cutout.png"))
    with open(os.path.join(ROOT, "graphs/own_photo.yaml"), encoding="utf-8") as f:
        g = f.read()
    subs = {"assets/own_cutout.png": "cutout.png", "assets/own_photo.jpg": "photo.jpg",
            "foot: [270, 345]": f"foot: [{270 * k:g}, {345 * k:g}]",
            "junction_points: [0, 262, 640, 292]": f"junction_points: [0, {262 * k:g}, {640 * k:g}, {292 * k:g}]",
            "inputs: {image: photo.image}}": f"inputs: {{image: photo.image}}, params: {{horizon: {120 * k:g}}}}}",
            "thickness: 6": f"thickness: {6 * k:g}"}
    for old, new in subs.items():
        if old not in g:
            raise SystemExit(f"graphs/own_photo.yaml changed: {old!r} not found; update photo_scene")
        g = g.replace(old, new)
    path = os.path.join(folder, "g.yaml")
    with open(path, "w", encoding="utf-8") as f:
        f.write(g)
    return path


def _children_cpu() -> float:
    """CPU seconds (user + sys) of the child processes waited for so far."""
    import resource

    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _ran_counts(out: str, rows: int) -> dict[str, int]:
    """How many of the batch's rows computed each node (from the rows' sidecars)."""
    counts: dict[str, int] = {}
    for i in range(rows):
        with open(os.path.join(out, f"{i:04d}.png.json"), encoding="utf-8") as f:
            for n in json.load(f)["ran"]:
                counts[n] = counts.get(n, 0) + 1
    return counts


def photo_bench(args) -> None:
    """6 light positions on a 20 MP photo: a loop of ``pixgraph run`` vs one ``pixgraph batch``."""
    tmp = tempfile.mkdtemp(prefix="batch_photo_")
    exe = [sys.executable, "-m", "pixgraph"]
    env = dict(os.environ, OMP_NUM_THREADS="1")
    az = [-60 + 24 * i for i in range(args.photo_rows)]
    load0 = os.getloadavg()
    report = {"machine": cpu_model(), "size": [args.photo_width, args.photo_height], "rows": len(az),
              "repeats": args.repeats, "load_start": load0, "walls": {}}
    print(f"machine: {cpu_model()}; load average at start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    try:
        graph = photo_scene(tmp, args.photo_width, args.photo_height)
        print(f"{len(az)} light azimuths on a {args.photo_width}x{args.photo_height} photo, "
              f"repeats {args.repeats}, wall seconds end to end, medians\n")
        modes = args.photo_modes.split(",")
        for rep in range(args.repeats):
            for mode in modes:
                out = os.path.join(tmp, f"{mode}-{rep}")
                cache = ["--disk-cache", os.path.join(tmp, f"cache-{mode}-{rep}")] if mode.endswith("-disk") \
                    else ["--no-disk-cache"]
                t0, c0 = time.perf_counter(), _children_cpu()
                if mode.startswith("cli-loop"):
                    for i, a in enumerate(az):
                        subprocess.run(exe + ["run", graph, "-q", *cache, "--set", f"light.azimuth={a}",
                                              "-o", f"final={out}/{i:04d}.png"], check=True, env=env)
                else:
                    extra = ["--cache-bytes", str(args.photo_cache_bytes)] if args.photo_cache_bytes else []
                    if "-p" in mode:  # batch-p2, batch-p2-disk: --processes 2
                        extra += ["--processes", mode.split("-p", 1)[1].split("-")[0]]
                    if "-inline" in mode:  # batch-inline: each row's files written before the next row
                        extra += ["--no-overlap"]
                    subprocess.run(exe + ["batch", graph, "-q", *cache, *extra, "--sweep",
                                          "light.azimuth=" + ",".join(map(str, az)),
                                          "-o", f"final={out}/{{index:04d}}.png", "--report",
                                          os.path.join(tmp, f"{mode}-{rep}.json")], check=True, env=env)
                wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
                report["walls"].setdefault(mode, []).append(wall)
                report.setdefault("cpus", {}).setdefault(mode, []).append(cpu)
                if not mode.startswith("cli-loop"):
                    report.setdefault("ran", {})[mode] = _ran_counts(out, len(az))
                print(f"  repeat {rep} {mode}: wall {wall:.1f} s, CPU {cpu:.1f} s (user+sys), "
                      f"load {os.getloadavg()[0]:.1f}", flush=True)
                shutil.rmtree(out, ignore_errors=True)
                shutil.rmtree(os.path.join(tmp, f"cache-{mode}-{rep}"), ignore_errors=True)
        print("\n| mode | wall s (median) | s per composite | speed-up vs cli-loop (same cache) "
              "| CPU s (median) | CPU ratio |")
        print("|---|---|---|---|---|---|")
        med = {m: statistics.median(w) for m, w in report["walls"].items()}
        cmed = {m: statistics.median(c) for m, c in report["cpus"].items()}
        for mode in modes:
            key = "cli-loop-disk" if mode.endswith("-disk") else "cli-loop"
            base, cbase = med.get(key), cmed.get(key)
            ratio = f"{base / med[mode]:.2f}x" if base else "-"
            cratio = f"{cbase / cmed[mode]:.2f}x" if cbase else "-"
            print(f"| {mode} | {med[mode]:.1f} | {med[mode] / len(az):.1f} | {ratio} | {cmed[mode]:.1f} | {cratio} |")
        for mode, counts in report.get("ran", {}).items():
            print(f"{mode}: nodes computed over the {len(az)} rows (sidecars' 'ran'): " +
                  ", ".join(f"{n} {k}" for n, k in sorted(counts.items())))
        report["medians"] = med
        report["cpu_medians"] = cmed
        _print_report(report)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _print_report(report: dict) -> None:
    """The load average at the end (kept in ``report``), then the report as one JSON line."""
    load1 = os.getloadavg()
    report["load_end"] = load1
    print(f"\nload average at end {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
    print("\n" + json.dumps(report))


#: functions of the soft shadow node whose time the profile reports separately (cProfile,
#: cumulative; missing ones are left out): the trace at the proxy, and the work that does not
#: depend on the light (input checks, proxy downsampling, the full-size upsample)
SHADOW_PARTS = {"trace (launch_banded)": ("shadow.py", "launch_banded"),
                "proxy inputs (resample.scene)": ("resample.py", "scene"),
                "upsample (masked_resize)": ("upsample.py", "masked_resize"),
                "input checks (check_inputs)": ("_shadow_ports.py", "check_inputs")}


def photo_profile(args) -> None:
    """Where a 20 MP light sweep's time goes: per node (wall and CPU) and per write, one
    session, the rows of a batch run in line (the first row also computes the shared
    upstream), medians over rows 2..; the soft shadow split by cProfile into its parts."""
    import cProfile
    import pstats

    from pixgraph.events import NodeFinished, NodeStarted
    from pixgraph_batch.files import write_atomic
    from pixgraph.session import Session

    tmp = tempfile.mkdtemp(prefix="batch_profile_")
    try:
        graph = photo_scene(tmp, args.photo_width, args.photo_height)
        t0 = time.perf_counter()
        s = Session()
        g = s.load(graph)
        print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}; session {time.perf_counter() - t0:.2f} s")
        print("wall s / CPU s (process user+sys, all threads) per part\n")
        rows = []
        for i, a in enumerate(-60 + 24 * k for k in range(args.photo_rows)):
            timings, cpu, started = {}, {}, {}

            def on_event(e):
                if isinstance(e, NodeStarted):
                    started[e.node_id] = time.process_time()
                elif isinstance(e, NodeFinished):
                    timings[e.node_id] = e.seconds
                    cpu[e.node_id] = time.process_time() - started.get(e.node_id, time.process_time())

            prof = cProfile.Profile()
            t0, c0 = time.perf_counter(), time.process_time()
            plan = s.plan(g, ["final"], params={"light.azimuth": a})
            t1, c1 = time.perf_counter(), time.process_time()
            prof.enable()
            res = s.run_plan(plan, on_event=on_event)
            prof.disable()
            t2, c2 = time.perf_counter(), time.process_time()
            digest = write_atomic(os.path.join(tmp, f"{i}.png"),
                                  lambda p: s.write_output(g, "final", res["final"], p))
            t3, c3 = time.perf_counter(), time.process_time()
            stats = pstats.Stats(prof).stats
            parts = {}
            for label, (fname, func) in SHADOW_PARTS.items():
                hits = [v[3] for (f, _, fn), v in stats.items() if f.endswith(fname) and fn == func]
                if hits:
                    parts[label] = sum(hits)
            rows.append({"plan": t1 - t0, "run": t2 - t1, "write_png": t3 - t2, "nodes": timings,
                         "cpu": {"plan": c1 - c0, "run": c2 - c1, "write_png": c3 - c2, "nodes": cpu},
                         "shadow_parts": parts, "sha": digest[:8]})
            print(f"row {i}: plan {t1 - t0:.2f}/{c1 - c0:.2f}, run {t2 - t1:.2f}/{c2 - c1:.2f} "
                  f"({', '.join(f'{k} {v:.2f}/{cpu.get(k, 0.0):.2f}' for k, v in timings.items())}), "
                  f"write PNG {t3 - t2:.2f}/{c3 - c2:.2f}; shadow: "
                  f"{', '.join(f'{k} {v:.2f}' for k, v in parts.items())}", flush=True)
        later = rows[1:]
        med = {k: statistics.median(r[k] for r in later) for k in ("plan", "run", "write_png")}
        cmed = {k: statistics.median(r["cpu"][k] for r in later) for k in ("plan", "run", "write_png")}
        nodes = sorted({n for r in later for n in r["nodes"]})
        print("\nrows 2..: median wall/CPU s: " + ", ".join(f"{k} {med[k]:.2f}/{cmed[k]:.2f}" for k in med) +
              "; nodes: " + ", ".join(f"{n} {statistics.median(r['nodes'].get(n, 0.0) for r in later):.2f}/"
                                      f"{statistics.median(r['cpu']['nodes'].get(n, 0.0) for r in later):.2f}"
                                      for n in nodes))
        labels = [k for k in SHADOW_PARTS if all(k in r["shadow_parts"] for r in later)]
        if labels:
            print("rows 2..: soft shadow parts, median wall s (cProfile, cumulative): " +
                  ", ".join(f"{k} {statistics.median(r['shadow_parts'][k] for r in later):.2f}" for k in labels))
        total = med["plan"] + med["run"] + med["write_png"]
        shadow = statistics.median(r["nodes"].get("shadow", 0.0) for r in later)
        print(f"rows 2..: the shadow node is {shadow:.2f} of {total:.2f} s wall per row ({100 * shadow / total:.0f} %)")
        first_only = {n: v for n, v in rows[0]["nodes"].items() if n not in nodes}
        print("first row only (shared upstream), wall/CPU s: " +
              ", ".join(f"{n} {v:.2f}/{rows[0]['cpu']['nodes'].get(n, 0.0):.2f}" for n, v in first_only.items()) +
              f" = {sum(first_only.values()):.2f}/{sum(rows[0]['cpu']['nodes'].get(n, 0.0) for n in first_only):.2f}")
        print(json.dumps({"rows": rows, "machine": cpu_model(), "load": os.getloadavg()}))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def png_bench(args) -> None:
    """Writing a 20 MP image as PNG: pixgraph's writer (Up filter + ISA-L deflate, and its
    zlib fallback and levels) vs libpng through OpenImageIO and Pillow at several zlib
    levels, and JPEG for scale; CPU and wall seconds (medians) and file sizes. The image:
    the photo of ``photo_scene`` (a photo with grain, as the composite's pixels mostly are),
    linear float RGB, as a composite reaches the writer."""
    import numpy as np

    from pixgraph_nodes.ops import imageio, png

    tmp = tempfile.mkdtemp(prefix="batch_png_")
    try:
        photo_scene(tmp, args.photo_width, args.photo_height)
        img, _ = imageio.read_image(os.path.join(tmp, "photo.jpg"))
        codes = imageio._encode_srgb8(img, None)
        h, w, c = img.shape
        print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}; image {w}x{h}x{c} "
              f"({w * h / 1e6:.1f} MP), repeats {args.repeats}, medians; isal "
              f"{'installed' if png._isal is not None else 'NOT installed'}\n")
        out = os.path.join(tmp, "out")

        def oiio_png(level):
            oiio = imageio._oiio()
            spec = oiio.ImageSpec(w, h, c, oiio.UINT8)
            spec.attribute("png:compressionLevel", level)
            o = oiio.ImageOutput.create(out + ".png")
            o.open(out + ".png", spec)
            o.write_image(codes)
            o.close()
            return out + ".png"

        def ours(level, isal=True):
            saved = png._isal
            if not isal:
                png._isal = None
            try:
                with open(out + ".png", "wb") as f:
                    png.write_png(f, codes, level=level)
            finally:
                png._isal = saved
            return out + ".png"

        def encode():
            imageio._encode_srgb8(img, None)

        cases = [("sRGB encode float -> 8-bit codes (every writer below starts from these)", encode),
                 ("write_image .png, default (encode + ours, ISA-L)",
                  lambda: imageio.write_image(out + ".png", img)),
                 ("ours: Up filter + ISA-L level 1 (default)", lambda: ours(None)),
                 ("ours: Up filter + zlib level 1 (no isal)", lambda: ours(None, isal=False)),
                 ("ours: Up filter + zlib level 6", lambda: ours(6)),
                 ("ours: Up filter + zlib level 9 (compression: 9)", lambda: ours(9)),
                 ("OpenImageIO libpng level 1 (the old default over 4 MP)", lambda: oiio_png(1)),
                 ("OpenImageIO libpng level 6 (the old default)", lambda: oiio_png(6))]
        try:
            from PIL import Image

            def pil(**kw):
                Image.fromarray(codes).save(out + (".jpg" if "quality" in kw else ".png"), **kw)
                return out + (".jpg" if "quality" in kw else ".png")

            for lv in (1, 3, 6):
                cases.append((f"Pillow compress_level {lv}", lambda lv=lv: pil(compress_level=lv)))
            cases.append(("Pillow JPEG quality 95 (for scale)", lambda: pil(quality=95)))
        except ImportError:
            print("(Pillow not installed: its rows left out)")
        try:
            import cv2  # noqa: F401

            for lv in (1, 3):
                cases.append((f"OpenCV imwrite PNG level {lv}",
                               lambda lv=lv: cv2.imwrite(out + ".png", codes[:, :, ::-1],
                                                         [cv2.IMWRITE_PNG_COMPRESSION, lv]) and out + ".png"))
        except ImportError:
            print("(OpenCV not installed: its rows left out)")
        print("| writer | CPU s | wall s | MB |")
        print("|---|---|---|---|")
        report = {"machine": cpu_model(), "size": [w, h], "rows": {}}
        for label, fn in cases:
            walls, cpus, size = [], [], None
            for _ in range(args.repeats):
                t0, c0 = time.perf_counter(), time.process_time()
                path = fn()
                walls.append(time.perf_counter() - t0)
                cpus.append(time.process_time() - c0)
                if path:
                    size = os.path.getsize(path)
                    if path.endswith(".png") and "ours" in label:  # the file decodes to the codes
                        back, _ = imageio._read_float(imageio._oiio(), path, keep_uint8=True)
                        assert np.array_equal(back, codes), label
            cw, ww = statistics.median(cpus), statistics.median(walls)
            report["rows"][label] = {"cpu": cw, "wall": ww, "bytes": size}
            print(f"| {label} | {cw:.2f} | {ww:.2f} | {size / 1e6:.1f} |" if size else
                  f"| {label} | {cw:.2f} | {ww:.2f} | - |", flush=True)
        print(f"\nload average at end {os.getloadavg()[0]:.2f}")
        print(json.dumps(report))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=200)
    ap.add_argument("--cli-rows", type=int, default=8, help="rows of the per-call CLI loop")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--workers-per-machine", type=int, default=2)
    ap.add_argument("--sim-rows", type=int, default=10000, help="rows of the simulated scale-out")
    ap.add_argument("--graphs", default="classical,ssn")
    ap.add_argument("--modes", default="inprocess,cli-loop,processes,dask")
    ap.add_argument("--photo", action="store_true", help="the 20 MP light sweep instead (issue 22)")
    ap.add_argument("--photo-rows", type=int, default=6)
    ap.add_argument("--photo-width", type=int, default=5120)
    ap.add_argument("--photo-height", type=int, default=3840)
    ap.add_argument("--photo-modes", default="cli-loop,batch,cli-loop-disk,batch-disk",
                    help="comma-separated: cli-loop, batch, batch-inline (--no-overlap), batch-pN (--processes N), "
                         "each with -disk (a fresh disk cache)")
    ap.add_argument("--photo-cache-bytes", type=int, default=0, help="batch --cache-bytes (0: the default)")
    ap.add_argument("--photo-profile", action="store_true", help="where a 20 MP light sweep's row time goes")
    ap.add_argument("--png", action="store_true", help="PNG writers side by side on a 20 MP image (CPU, wall, size)")
    args = ap.parse_args()
    if args.png:
        png_bench(args)
        return
    if args.photo_profile:
        photo_profile(args)
        return
    if args.photo:
        photo_bench(args)
        return
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    import torch

    torch.set_num_threads(1)
    load0 = os.getloadavg()
    print(f"machine: {cpu_model()}; load average at start {load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}")
    print(f"rows {args.rows} (cli-loop {args.cli_rows}), 512x512, repeats {args.repeats}, medians\n")
    tmp = tempfile.mkdtemp(prefix="batch_bench_")
    report = {"machine": cpu_model(), "rows": args.rows, "cli_rows": args.cli_rows, "repeats": args.repeats,
              "load_start": load0, "results": {}}
    try:
        print("| graph | mode | rows | wall s (median) | composites/s | per-row s in worker (median) |")
        print("|---|---|---|---|---|---|")
        for gname in args.graphs.split(","):
            graph = GRAPHS[gname]
            for mode in args.modes.split(","):
                walls, per_row = [], []
                n = args.cli_rows if mode == "cli-loop" else args.rows
                for rep in range(args.repeats):
                    out = os.path.join(tmp, f"{gname}-{mode}-{rep}")
                    if mode == "cli-loop":
                        walls.append(run_cli_loop(graph, n, out))
                    else:
                        w, secs = run_batch(graph, n, mode, 1 if mode == "inprocess" else args.workers, out)
                        walls.append(w)
                        per_row.extend(secs[1:] if len(secs) > 1 else secs)  # the first row opens the device
                    shutil.rmtree(out, ignore_errors=True)
                wall = statistics.median(walls)
                row_s = statistics.median(per_row) if per_row else float("nan")
                report["results"][f"{gname}/{mode}"] = {"rows": n, "walls": walls, "wall_median": wall,
                                                       "throughput": n / wall, "per_row_median": row_s}
                print(f"| {gname} | {mode} | {n} | {wall:.2f} | {n / wall:.2f} | "
                      f"{'-' if mode == 'cli-loop' else f'{row_s:.3f}'} |", flush=True)
        if "dask" in args.modes:
            start, t_sched = scheduler_overhead()
            report["dask_start_s"], report["dask_task_overhead_s"] = start, t_sched
            print(f"\nDask LocalCluster(2) start {start:.2f} s; scheduler overhead {t_sched * 1e3:.2f} ms per task")
            w = args.workers_per_machine
            for gname in args.graphs.split(","):
                t_row = report["results"][f"{gname}/dask"]["per_row_median"]
                rows = args.sim_rows
                print(f"\nsimulated scale-out, {gname}: {rows} rows, t_row {t_row:.3f} s, "
                      f"{w} workers per machine, startup {start:.1f} s")
                print("| machines | composites/s | bound by |")
                print("|---|---|---|")
                sim = {}
                for machines in (1, 2, 4, 8, 16, 32, 64, 128, 256):
                    work = rows * t_row / (machines * w)
                    sched = rows * t_sched
                    total = start + max(work, sched)
                    sim[machines] = rows / total
                    print(f"| {machines} | {rows / total:.1f} | {'workers' if work >= sched else 'scheduler'} |")
                report["results"][f"{gname}/scale_out"] = sim
        _print_report(report)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
