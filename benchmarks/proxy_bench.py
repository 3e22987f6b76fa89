"""The classical soft shadow of large images at a proxy resolution
(``ops.upsample.proxy_soft_shadow``) against the full-resolution trace.

    python benchmarks/proxy_bench.py --data data/wall_test --factor 4 --limit 8 --proxy 256 --proxy 512
    python benchmarks/proxy_bench.py --data data/wall_test --factor 8 --limit 2 --proxy 512 --proxy 1024
    python benchmarks/proxy_bench.py --data data/wall_test --factor 16 --limit 1 --proxy 1024 --no-full

Benchmark scenes (256^2) are enlarged ``--factor`` times (``pixgraph_lab.rescale``:
1024^2, 2048^2, 4096^2). For each, ``--samples`` light samples (default 64):

* ``rmse_full``: RMSE of the proxy's darkness against the full-resolution
  trace's, over background pixels (outside the cutout), and the max |error|;
* ``rmse_gt``: both shrunk back to 256^2 against the Mitsuba ground truth
  (does the proxy change the accuracy that counts?);
* ``s``: wall-clock seconds of one call (after a warm-up at a 256-px proxy);
  with ``--memory`` each call runs in a fresh process, which also reports
  ``added_mib``: the peak resident memory during the call above what the
  process (torch, OpenCL, the full-size inputs) held just before it (Linux:
  the peak is reset through /proc/self/clear_refs).

With ``--photo SIZE`` (``20mp``, ``5mp``, ``1280``: the own-photo scene of
``benchmarks/photo_bench.py``, its cutout placed on a photo of that size, 48
samples as that graph) the inputs come from the graph instead, and each
``--proxy`` (0: the full trace, always run first and kept under out/bench/photo/)
is compared with the full trace: darkness RMSE over background pixels, max
|error|, and the CPU and wall seconds of ``proxy_soft_shadow``:

    python benchmarks/proxy_bench.py --photo 20mp --photo 5mp --proxy 512 --proxy 768 --proxy 1024 --proxy 2048

Machine and medians are printed. Nothing here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from _machine import cpu_model, peak_rss_mib


def _scene(data, index, factor):
    from pixgraph.device import Device
    from pixgraph_lab.datagen.dataset import sample_files
    from pixgraph_lab.evaluate import prepared_sample
    from pixgraph_lab.rescale import rescaled
    dev = Device.open()
    s = prepared_sample(sample_files(data)[index], dev)
    return s, rescaled(s, factor), dev


def _trace(dev, big, samples, side):
    from pixgraph_nodes.ops.lights import disk_samples
    from pixgraph_nodes.ops.upsample import proxy_soft_shadow
    pts = disk_samples(big["light"], big["camera"], samples)
    return 1.0 - proxy_soft_shadow(dev, big["mask"].astype(np.float32), big["fg_height"], big["bg_height"],
                                   pts, 1.0, side)


def one(a) -> int:
    """Subprocess mode: one trace; prints seconds and the peak resident memory it
    added (Linux: the peak is reset just before the trace) as JSON, and saves the
    darkness to ``--save``."""
    s, big, dev = _scene(a.data, a.index, a.factor)
    side = a.one if a.one > 0 else max(big["mask"].shape)
    _trace(dev, big, a.samples, 256)          # build the OpenCL program off the clock
    before = _rss_mib()
    with open("/proc/self/clear_refs", "w") as fh:   # reset the peak (VmHWM) to the current RSS
        fh.write("5")
    t0 = time.perf_counter()
    d = _trace(dev, big, a.samples, side)
    sec = time.perf_counter() - t0
    peak = peak_rss_mib()
    if a.save:
        np.save(a.save, d.astype(np.float32))
    print(json.dumps({"s": sec, "peak_mib": peak, "before_mib": before}))
    return 0


def _rss_mib() -> float:
    """Current resident memory [MiB] (Linux /proc)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * resource.getpagesize() / 2 ** 20


def photo(a) -> int:
    """``--photo``: each proxy against the full trace on the own-photo scene (see the docstring)."""
    import pathlib
    sys.path.insert(0, str(pathlib.Path(__file__).parent))
    import photo_bench as PB
    from pixgraph.device import Device
    from pixgraph.session import Session
    from pixgraph_nodes.ops.lights import disk_samples
    from pixgraph_nodes.ops.upsample import proxy_soft_shadow
    dev = Device.open()
    print(f"# proxy soft shadow on the own-photo scene; {cpu_model()}; load average {os.getloadavg()[0]:.2f}")
    print("| photo | trace | CPU s | wall s | darkness RMSE vs full | max abs. error |")
    print("|---|---|---|---|---|---|")
    rows = []
    for size in a.photo:
        g = PB.make_graph("soft", size)
        s = Session(disk_cache=None, allow_paths=[str(PB.ROOT)])
        r = s.run(g, outputs=["place.alpha", "place.height", "bg_h.height", "light.light", "cam.camera"])
        mask, fg, bg = r["place.alpha"], r["place.height"], r["bg_h.height"]
        samples = disk_samples(r["light.light"], r["cam.camera"], 48, 0)
        thickness = 6.0 * mask.shape[1] / 640.0               # photo_bench's graph: 6 px at 640 px
        H, W = mask.shape
        bgpx = mask < 0.5
        saved = PB.OUT / f"full_trace_{size}.npy"

        def trace(side):
            c0, t0 = time.process_time(), time.perf_counter()
            d = 1.0 - proxy_soft_shadow(dev, mask, fg, bg, samples, thickness, side if side > 0 else max(H, W))
            return d, time.process_time() - c0, time.perf_counter() - t0
        if saved.exists() and not a.recompute:
            full = np.load(saved)
            cpu = wall = float("nan")
        else:
            full, cpu, wall = trace(0)
            saved.parent.mkdir(parents=True, exist_ok=True)
            np.save(saved, full.astype(np.float32))
        took = f"{cpu:.2f} | {wall:.2f}" if cpu == cpu else f"(read from {saved.name}) | —"
        print(f"| {W}x{H} | full | {took} | — | — |", flush=True)
        for side in a.proxy or [1024]:
            d, cpu, wall = trace(side)
            e = (d.astype(np.float64) - full)[bgpx]
            row = {"size": f"{W}x{H}", "proxy": side, "cpu_s": cpu, "s": wall,
                   "rmse": float(np.sqrt(np.mean(e ** 2))), "max": float(np.abs(e).max())}
            rows.append(row)
            print(f"| {W}x{H} | proxy {side} | {cpu:.2f} | {wall:.2f} | {row['rmse']:.4f} | {row['max']:.3f} |",
                  flush=True)
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"machine": cpu_model(), "args": vars(a), "rows": rows}, fh, indent=1)
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default="data/wall_test")
    ap.add_argument("--factor", type=int, default=4)
    ap.add_argument("--limit", type=int, default=4)
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--proxy", type=int, action="append", default=None)
    ap.add_argument("--no-full", action="store_true", help="skip the full-resolution trace (time only)")
    ap.add_argument("--memory", action="store_true", help="also measure peak RSS in fresh processes")
    ap.add_argument("--json", default=None)
    ap.add_argument("--photo", action="append", choices=("20mp", "5mp", "1280"),
                    help="the own-photo scene of photo_bench.py at this size instead of --data")
    ap.add_argument("--recompute", action="store_true", help="--photo: trace the full resolution again")
    ap.add_argument("--one", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--index", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--save", default=None, help=argparse.SUPPRESS)
    a = ap.parse_args(argv)
    if a.one is not None:
        return one(a)
    if a.photo:
        return photo(a)
    import torch
    torch.set_num_threads(1)
    from pixgraph_lab.metrics import shadow_metrics
    from pixgraph_nodes.ops.resample import resize
    proxies = a.proxy or [512]
    rows = []
    for i in range(a.limit):
        s, big, dev = _scene(a.data, i, a.factor)
        H, W = big["mask"].shape
        inside = big["mask"]
        g = s["shadow"].astype(np.float64)
        valid = ~s["mask"] & s["bg_valid"]
        res = {"index": i, "size": f"{W}x{H}"}

        def run(side):
            if not a.memory:
                t0 = time.perf_counter()
                d = _trace(dev, big, a.samples, side)
                return d, time.perf_counter() - t0, None
            with tempfile.TemporaryDirectory() as tmp:
                path = os.path.join(tmp, "d.npy")
                out = subprocess.run([sys.executable, __file__, "--data", a.data, "--factor", str(a.factor),
                                      "--samples", str(a.samples), "--index", str(i), "--one", str(side),
                                      "--save", path], capture_output=True, text=True, check=True).stdout
                got = json.loads(out.strip().splitlines()[-1])
                return np.load(path), got["s"], got["peak_mib"] - got["before_mib"]

        if not a.memory:
            _trace(dev, big, a.samples, 256)                   # warm-up
        full = None
        if not a.no_full:
            full, res["full_s"], mem = run(max(H, W))
            if mem is not None:
                res["full_added_mib"] = mem
            res["full_rmse_gt"] = shadow_metrics(resize(full, s["shadow"].shape), g, valid)["rmse"]
        for p in proxies:
            d, res[f"p{p}_s"], mem = run(p)
            if mem is not None:
                res[f"p{p}_added_mib"] = mem
            res[f"p{p}_rmse_gt"] = shadow_metrics(resize(d, s["shadow"].shape), g, valid)["rmse"]
            if full is not None:
                e = (d - full)[~inside]
                res[f"p{p}_rmse_full"] = float(np.sqrt(np.mean(e ** 2)))
                res[f"p{p}_max_full"] = float(np.abs(e).max())
        print(json.dumps(res), flush=True)
        rows.append(res)
    keys = [k for k in rows[0] if k not in ("index", "size")]
    print(f"# proxy soft shadow, {a.samples} samples, {rows[0]['size']} ({a.limit} scenes of {a.data} x{a.factor});"
          f" {cpu_model()}")
    for k in keys:
        v = [r[k] for r in rows if k in r]
        agg = statistics.median(v) if k.endswith(("_s", "_mib")) else float(np.mean(v))
        what = "median" if k.endswith(("_s", "_mib")) else ("max" if "max" in k else "mean")
        if what == "max":
            agg = float(np.max(v))
        print(f"{k}: {agg:.4g} ({what})")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"machine": cpu_model(), "args": vars(a), "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
