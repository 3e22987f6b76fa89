"""Learned cutout pixel-height inference time at 256^2 on this machine (goal: <= 30 ms, issue 24).

    python benchmarks/height_bench.py [--weights nodes/weights/cutout_height.pt] [--threads N] [--runs 31]
    python benchmarks/height_bench.py --size 2048 --runs 9 --own-size     # a large cutout: the work-size path
    python benchmarks/height_bench.py --size 400 --canvas 5120x3840 --runs 9   # a matte at a 20 MP photo's size

Times, median (and min) wall time and median process CPU time over ``--runs`` after warm-up, on a ``--size``
square RGBA cutout (default 256; a shaded upright figure-like shape drawn procedurally, filling about
half the image): the whole ``LearnedHeightPredictor.predict`` (crop, resize,
the contact-line channel, the network, paste back) and the network alone; and
the contact-line heuristic for comparison; with ``--own-size`` also the path
shipped before the fifth session, alternating run by run with the shipped one
(a cutout larger than 512 px is now predicted at 512 px). Nothing here is
asserted by the tests.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import sys
import time

import numpy as np

from _machine import cpu_model

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_cutout(size: int = 256) -> np.ndarray:
    """A premultiplied RGBA (size, size, 4): an ellipse body on two legs, shaded."""
    v, u = np.mgrid[0:size, 0:size] + 0.5
    s = size / 256
    body = ((u - 128 * s) / (40 * s)) ** 2 + ((v - 100 * s) / (60 * s)) ** 2 < 1
    legs = ((np.abs(u - 112 * s) < 8 * s) | (np.abs(u - 144 * s) < 8 * s)) & (v > 140 * s) & (v < 220 * s)
    a = (body | legs).astype(np.float32)
    shade = 0.3 + 0.6 * np.clip((u - 80 * s) / (100 * s), 0, 1)
    rgb = np.stack([0.8 * shade, 0.4 * shade, 0.3 * shade], -1) * a[..., None]
    return np.concatenate([rgb, a[..., None]], -1).astype(np.float32)


def timed(fn, runs: int) -> tuple[float, float, float]:
    """(median wall ms, min wall ms, median process CPU ms: user + sys of this process,
    which a busy machine inflates less than wall time)."""
    fn(); fn()
    ts, cs = [], []
    for _ in range(runs):
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        ts.append(1e3 * (time.perf_counter() - t0))
        cs.append(1e3 * (time.process_time() - c0))
    return statistics.median(ts), min(ts), statistics.median(cs)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", default=str(ROOT / "nodes" / "weights" / "cutout_height.pt"))
    ap.add_argument("--threads", type=int, default=1,
                    help="torch threads of the predictor (its default is 1; 0: torch's default)")
    ap.add_argument("--runs", type=int, default=31)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--baseline", default=None,
                    help="a second checkpoint timed in the same run, interleaved (ratios on a busy machine)")
    ap.add_argument("--canvas", metavar="WxH", default=None,
                    help="the cutout in the middle of a transparent canvas this size (a matte at a photo's size)")
    ap.add_argument("--own-size", action="store_true",
                    help="also time the path shipped before the fifth session (everything at the cutout's own "
                         "size: work_side = signal_side = None), alternating with the shipped one")
    a = ap.parse_args(argv)
    import torch
    sys.path.insert(0, str(ROOT))
    from pixgraph_nodes.ops.heightmaps import contact_line_height
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor, prepare, straight_srgb
    pred = LearnedHeightPredictor(a.weights, threads=a.threads or None)
    rgba = test_cutout(a.size)
    if a.canvas:
        cw, ch = (int(v) for v in a.canvas.lower().split("x"))
        canvas = np.zeros((ch, cw, 4), np.float32)
        top, left = (ch - a.size) // 2, (cw - a.size) // 2
        canvas[top:top + a.size, left:left + a.size] = rgba
        rgba = canvas
    colour, alpha = straight_srgb(rgba)
    x, _, _ = prepare(colour, alpha, pred.size)
    n_params = sum(p.numel() for p in pred.model.parameters())
    load0 = os.getloadavg()[0]
    whole = timed(lambda: pred.predict_full(rgba), a.runs)
    net = timed(lambda: pred.predict_normalised(x[None]), a.runs)
    heur = timed(lambda: contact_line_height(rgba[..., 3]), a.runs)
    print(f"machine: {cpu_model()}, torch {torch.__version__}, predictor threads "
          f"{a.threads or torch.get_num_threads()}")
    print(f"model: {a.weights} ({n_params} parameters, runs at {pred.size}^2)")
    print(f"input {a.size}x{a.size}{' on a ' + a.canvas + ' canvas' if a.canvas else ''}, median wall ms (min wall) [median CPU ms] of {a.runs} runs; "
          f"load average {load0:.1f} before, {os.getloadavg()[0]:.1f} after:")
    print(f"  learned predict_full     {whole[0]:7.1f} ms ({whole[1]:.1f}) [{whole[2]:.1f}] "
          "(pinned, foot snap and confidence as the checkpoint says)")
    print(f"  network alone            {net[0]:7.1f} ms ({net[1]:.1f}) [{net[2]:.1f}]")
    print(f"  contact-line heuristic   {heur[0]:7.1f} ms ({heur[1]:.1f}) [{heur[2]:.1f}]")
    if a.own_size:
        ts = {"shipped": [], "own": []}
        keep = pred.work_side, pred.signal_side

        def own():
            pred.work_side, pred.signal_side = None, None
            try:
                pred.predict_full(rgba)
            finally:
                pred.work_side, pred.signal_side = keep
        own()
        for _ in range(a.runs):
            for name, fn in (("shipped", lambda: pred.predict_full(rgba)), ("own", own)):
                t0 = time.perf_counter()
                fn()
                ts[name].append(1e3 * (time.perf_counter() - t0))
        s_, o_ = statistics.median(ts["shipped"]), statistics.median(ts["own"])
        print(f"  alternating, {a.runs} runs each: shipped predict_full {s_:.1f} ms, at its own size "
              f"(before the fifth session) {o_:.1f} ms; ratio {s_ / o_:.2f}")
    if a.baseline:
        base = LearnedHeightPredictor(a.baseline, threads=a.threads or None)
        b = timed(lambda: base.predict_full(rgba), a.runs)
        print(f"  baseline {a.baseline} predict_full {b[0]:7.1f} ms ({b[1]:.1f}) [{b[2]:.1f}]; "
              f"ratio {whole[0] / b[0]:.2f}")
    w = pathlib.Path(a.weights).stat().st_size
    print(f"weights {w / 1e6:.2f} MB (goal <= 20 MB: {'met' if w <= 20e6 else 'missed'})")
    if a.size == 256:
        print(f"goal <= 30 ms (wall, one thread, quiet machine): {'met' if whole[0] <= 30 else 'missed'} here "
              f"(CPU {whole[2]:.1f} ms)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
