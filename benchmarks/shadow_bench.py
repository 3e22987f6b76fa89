"""Benchmark of the pixel-height shadow tracers (not a test).

    python benchmarks/shadow_bench.py [--device SPEC] [--runs 7] [--quick]

Scene: a standing figure-like cutout (head, body, arms, legs; its bounding box
about a quarter of the image) on a ground + back-wall background, lit by a
point light up and to the left in front of it (soft: a disk of radius 5% of the
image around it, stratified samples).

For each OpenCL CPU/GPU device (or the one ``--device`` names) it reports the
median of ``--runs`` runs after two warm-up runs:
  kernel  the launch and its completion on a scene already on the device
          (ShadowScene: inputs uploaded once, output buffer reused), no read-back;
  e2e     the public function call from numpy arrays to numpy arrays (host
          preparation, uploads, launch, read-back).
  banded  the same call as the nodes make it, with progress and cancellation
          callbacks (no-ops here): the image in bands of about
          shadow.BAND_WORK pixel-samples, one launch and one wait each
          (the numbers are the same as e2e's; only the time may differ).
Each with the CPU time the process used meanwhile (all threads): on a machine
shared with other work the wall time grows, the CPU time much less (wall time
is at least CPU time / number of cores).
It also prints the machine, the device, and the load average before and after
(other processes share the CPU; timings on a loaded machine are pessimistic).
"""
from __future__ import annotations

import argparse
import os
import platform
import resource
import statistics
import sys
import time

import numpy as np

from _machine import cpu_model
from pixgraph.device import Device, list_devices
from pixgraph_nodes.ops import buffers as B
from pixgraph_nodes.ops import shadow as S


def figure_scene(n: int):
    """Mask, cutout and background pixel heights (pixels) of the benchmark scene:
    the figure's bounding box covers about a quarter of the image."""
    s = 1.3 * n / 256.0
    i = np.arange(n, dtype=np.float64)[:, None] + 0.5
    j = np.arange(n, dtype=np.float64)[None, :] + 0.5
    cu, foot = 0.5 * n, 0.88 * n

    def ell(cx, cy, rx, ry):
        return ((j - cx) / rx) ** 2 + ((i - cy) / ry) ** 2 <= 1.0

    m = (ell(cu, foot - 118 * s, 14 * s, 16 * s) | ell(cu, foot - 70 * s, 26 * s, 36 * s)
         | ell(cu - 30 * s, foot - 72 * s, 7 * s, 28 * s) | ell(cu + 30 * s, foot - 72 * s, 7 * s, 28 * s))
    for du in (-12 * s, 12 * s):
        m |= (np.abs(j - (cu + du)) <= 6 * s) & (i >= foot - 45 * s) & (i <= foot)
    mask = m.astype(np.float32)
    fg = np.where(m, np.maximum(0.0, foot - i), 0.0).astype(np.float32)   # upright, stands on v = foot
    bg = np.broadcast_to(np.maximum(0.0, 0.45 * n - i), (n, n)).astype(np.float32)  # ground + wall
    return mask, fg, bg


def light_for(n: int):
    return np.array([0.2 * n, 0.3 * n, 0.5 * n, 1.0], np.float32)


def disk_samples(center, radius, count, seed=0):
    """Stratified samples of a disk of `radius` pixels in the (u, h) plane."""
    rng = np.random.default_rng(seed)
    k = int(np.ceil(np.sqrt(count)))
    a, b = np.meshgrid(np.arange(k), np.arange(k))
    x = ((a.ravel() + rng.random(k * k)) / k)[:count]
    y = ((b.ravel() + rng.random(k * k)) / k)[:count]
    r, t = radius * np.sqrt(x), 2 * np.pi * y
    out = np.tile(np.asarray(center, np.float64), (count, 1))
    out[:, 0] += r * np.cos(t)
    out[:, 2] += r * np.sin(t)
    return out.astype(np.float32)


def extremes(center, radius):
    c = np.asarray(center, np.float32)
    return np.array([c + [radius, 0, 0, 0], c - [radius, 0, 0, 0], c + [0, 0, radius, 0], c - [0, 0, radius, 0]],
                    np.float32)


#: what a node passes: progress and cancellation callbacks (no-ops here)
CALLBACKS = dict(progress=lambda fraction, message="": None, check_cancelled=lambda: None)


def _cpu_s():
    """CPU time of this process (all threads, PoCL's workers included), seconds."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def median_ms(fn, runs):
    """(median wall ms, median CPU ms) of `runs` calls after two warm-up calls."""
    for _ in range(2):
        fn()
    ts, cs = [], []
    for _ in range(runs):
        c = _cpu_s()
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
        cs.append(_cpu_s() - c)
    return 1e3 * statistics.median(ts), 1e3 * statistics.median(cs)


def machine() -> str:
    return f"{cpu_model()}, {platform.system()} {platform.release()}"


def bench_device(dev: Device, runs: int, quick: bool):
    rows = []
    sizes = (256, 512) if quick else (256, 512, 1024)
    for n in sizes:
        mask, fg, bg = figure_scene(n)
        L = light_for(n)
        scene = S.ShadowScene(dev, mask, fg, bg)
        k = median_ms(lambda: scene.launch_hard(L)[0].wait(), runs)
        e = median_ms(lambda: S.hard_shadow(dev, mask, fg, bg, L), runs)
        b = median_ms(lambda: S.hard_shadow(dev, mask, fg, bg, L, **CALLBACKS), runs)
        rows.append((f"hard shadow {n}x{n}", k, e, b, "<= 10 ms at 512" if n == 512 else ""))
    for n in (256, 512):
        mask, fg, bg = figure_scene(n)
        scene = S.ShadowScene(dev, mask, fg, bg)
        for count in (16, 64, 256):
            if quick and count == 256:
                continue
            samples = disk_samples(light_for(n), 0.05 * n, count)
            inputs = scene.soft_inputs(samples)
            k = median_ms(lambda: scene.launch_soft(inputs)[0].wait(), runs)
            e = median_ms(lambda: S.soft_shadow(dev, mask, fg, bg, samples), runs)
            b = median_ms(lambda: S.soft_shadow(dev, mask, fg, bg, samples, **CALLBACKS), runs)
            rows.append((f"soft shadow {n}x{n}, {count} samples", k, e, b,
                         "<= 300 ms" if (n, count) == (512, 64) else ""))
    n = 256
    mask, fg, bg = figure_scene(n)
    L = light_for(n)
    ex = extremes(L, 0.05 * n)
    scene = S.ShadowScene(dev, mask, fg, bg)
    lbuf = scene.samples_buffer(np.concatenate([L[None], ex]))
    k = median_ms(lambda: B.launch_channels(scene, lbuf)[0].wait(), runs)
    e = median_ms(lambda: B.buffer_channels(dev, mask, fg, bg, L, ex), runs)
    b = median_ms(lambda: B.buffer_channels(dev, mask, fg, bg, L, ex, **CALLBACKS), runs)
    rows.append((f"buffer channels {n}x{n}", k, e, b, "<= 30 ms"))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", help="device spec (pixgraph.device.choose); default: every device")
    ap.add_argument("--runs", type=int, default=7, help="timed runs per case (median), >= 5")
    ap.add_argument("--quick", action="store_true", help="skip 1024x1024 and 256 samples")
    args = ap.parse_args(argv)
    runs = max(5, args.runs)
    print(f"machine: {machine()}")
    print(f"load average before: {os.getloadavg()}")
    specs = [args.device] if args.device else [d.spec for d in list_devices()]
    for spec in specs:
        dev = Device.open(spec)
        print(f"\ndevice: {dev.name}")
        try:
            S.program(dev)
        except Exception as e:  # a platform that cannot compile here: report, go on
            print(f"  cannot build the kernels: {str(e).strip().splitlines()[-3:]}")
            continue
        mask = figure_scene(256)[0]
        rr, cc = np.nonzero(mask)
        print(f"  scene: cutout {mask.mean():.1%} of the image, its bounding box "
              f"{(np.ptp(rr) + 1) * (np.ptp(cc) + 1) / mask.size:.1%}")
        rows = bench_device(dev, runs, args.quick)
        print(f"  {'case':38s} {'kernel ms':>10s} {'(cpu ms)':>9s} {'e2e ms':>10s} {'(cpu ms)':>9s} "
              f"{'banded ms':>10s} {'(cpu ms)':>9s}  goal")
        for name, k, e, b, goal in rows:
            print(f"  {name:38s} {k[0]:10.2f} {k[1]:9.1f} {e[0]:10.2f} {e[1]:9.1f} {b[0]:10.2f} {b[1]:9.1f}  {goal}")
    print(f"\nload average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
