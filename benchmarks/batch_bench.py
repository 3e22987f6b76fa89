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
                t0 = time.perf_counter()
                if mode.startswith("cli-loop"):
                    for i, a in enumerate(az):
                        subprocess.run(exe + ["run", graph, "-q", *cache, "--set", f"light.azimuth={a}",
                                              "-o", f"final={out}/{i:04d}.png"], check=True, env=env)
                else:
                    extra = ["--cache-bytes", str(args.photo_cache_bytes)] if args.photo_cache_bytes else []
                    if "-p" in mode:  # batch-p2, batch-p2-disk: --processes 2
                        extra += ["--processes", mode.split("-p", 1)[1].split("-")[0]]
                    subprocess.run(exe + ["batch", graph, "-q", *cache, *extra, "--sweep",
                                          "light.azimuth=" + ",".join(map(str, az)),
                                          "-o", f"final={out}/{{index:04d}}.png", "--report",
                                          os.path.join(tmp, f"{mode}-{rep}.json")], check=True, env=env)
                wall = time.perf_counter() - t0
                report["walls"].setdefault(mode, []).append(wall)
                print(f"  repeat {rep} {mode}: {wall:.1f} s", flush=True)
                shutil.rmtree(out, ignore_errors=True)
                shutil.rmtree(os.path.join(tmp, f"cache-{mode}-{rep}"), ignore_errors=True)
        print("\n| mode | wall s (median) | s per composite | speed-up vs cli-loop (same cache) |")
        print("|---|---|---|---|")
        med = {m: statistics.median(w) for m, w in report["walls"].items()}
        for mode in modes:
            base = med.get("cli-loop-disk" if mode.endswith("-disk") else "cli-loop")
            ratio = f"{base / med[mode]:.2f}x" if base else "-"
            print(f"| {mode} | {med[mode]:.1f} | {med[mode] / len(az):.1f} | {ratio} |")
        report["medians"] = med
        load1 = os.getloadavg()
        report["load_end"] = load1
        print(f"\nload average at end {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
        print("\n" + json.dumps(report))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def photo_profile(args) -> None:
    """Where a 20 MP light sweep's time goes: per node and per write, one session, the
    rows of a batch (the first row also computes the shared upstream), medians."""
    from pixgraph.events import NodeFinished
    from pixgraph_batch.files import write_atomic
    from pixgraph.session import Session

    tmp = tempfile.mkdtemp(prefix="batch_profile_")
    try:
        graph = photo_scene(tmp, args.photo_width, args.photo_height)
        t0 = time.perf_counter()
        s = Session()
        g = s.load(graph)
        print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}; session {time.perf_counter() - t0:.2f} s")
        rows = []
        for i, a in enumerate(-60 + 24 * k for k in range(args.photo_rows)):
            timings = {}
            t0 = time.perf_counter()
            plan = s.plan(g, ["final"], params={"light.azimuth": a})
            t1 = time.perf_counter()
            res = s.run_plan(plan, on_event=lambda e: isinstance(e, NodeFinished) and
                             timings.__setitem__(e.node_id, e.seconds))
            t2 = time.perf_counter()
            digest = write_atomic(os.path.join(tmp, f"{i}.png"),
                                  lambda p: s.write_output(g, "final", res["final"], p))
            t3 = time.perf_counter()
            rows.append({"plan": t1 - t0, "run": t2 - t1, "write_png": t3 - t2, "nodes": timings, "sha": digest[:8]})
            print(f"row {i}: plan {t1 - t0:.2f} s, run {t2 - t1:.2f} s "
                  f"({', '.join(f'{k} {v:.2f}' for k, v in timings.items())}), write PNG {t3 - t2:.2f} s", flush=True)
        later = rows[1:]
        med = {k: statistics.median(r[k] for r in later) for k in ("plan", "run", "write_png")}
        nodes = sorted({n for r in later for n in r["nodes"]})
        print("\nrows 2..: median " + ", ".join(f"{k} {v:.2f} s" for k, v in med.items()) + "; nodes: " +
              ", ".join(f"{n} {statistics.median(r['nodes'].get(n, 0.0) for r in later):.2f}" for n in nodes))
        first_only = {n: v for n, v in rows[0]["nodes"].items() if n not in nodes}
        print("first row only (shared upstream): " + ", ".join(f"{n} {v:.2f}" for n, v in first_only.items()) +
              f" = {sum(first_only.values()):.2f} s")
        print(json.dumps({"rows": rows, "machine": cpu_model()}))
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
                    help="comma-separated: cli-loop, batch, batch-pN (--processes N), each with -disk (a fresh disk cache)")
    ap.add_argument("--photo-cache-bytes", type=int, default=0, help="batch --cache-bytes (0: the default)")
    ap.add_argument("--photo-profile", action="store_true", help="where a 20 MP light sweep's row time goes")
    args = ap.parse_args()
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
        load1 = os.getloadavg()
        report["load_end"] = load1
        print(f"\nload average at end {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
        print("\n" + json.dumps(report))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
