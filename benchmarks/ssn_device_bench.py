"""SSN++ on each torch device this machine has: the same prediction, and its time.

    python benchmarks/ssn_device_bench.py [--weights nodes/weights/ssnpp.pt] [--runs 21] [--size 256]

For the CPU and, where torch finds one, the first CUDA device (the choice
``PIXGRAPH_TORCH_DEVICE`` makes, ``nodes/ops/ssn.inference_device``), it runs
``ssn.predict`` on one fixed input at ``--size``^2 (``scene_buffers``: each channel
the network reads filled by its name, not by the renderer: the disc's 0/1 mask for
a name with "mask", "cutout" or "alpha" -- so ``cutout_height`` gets the mask --,
an ellipse of hard shadow beside it for "shadow" / "hard", the disc's pixel
heights for "height", "dist" or "ph" -- so ``relative_distance`` gets them --,
small smooth values otherwise, each plus seeded noise) and reports the median and
min over ``--runs`` after two warm-ups, and the largest difference of each
device's darkness from the CPU's. The input only has to be the same on every
device; ``benchmarks/ssn_bench.py`` times the node on the example scene's real
buffers (it needs OpenCL).
Needs torch only (no OpenCL), so it runs on a GPU machine with the repo's
``nodes`` importable as ``pixgraph_nodes``. Nothing here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import sys
import time

import numpy as np
import torch

ROOT = pathlib.Path(__file__).resolve().parents[1]


def scene_buffers(channels, size: int) -> dict[str, np.ndarray]:
    """A value for every channel in ``channels``, chosen by the channel's name (module
    doc; the first rule that matches wins): a disc standing on the ground, its pixel
    heights [px], an ellipse of hard shadow to its right, seeded noise of 1e-3."""
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
    r = size * 0.18
    cx, cy = size * 0.45, size * 0.55
    disc = ((xx - cx) ** 2 + (yy - cy) ** 2) < r * r
    foot = cy + r
    height = np.where(disc, np.maximum(foot - yy, 0.0), 0.0).astype(np.float32)
    shadow = (((xx - cx - r * 1.2) / (r * 1.6)) ** 2 + ((yy - foot + r * 0.2) / (r * 0.35)) ** 2 < 1) & ~disc
    rng = np.random.default_rng(0)
    out = {}
    for name in channels:
        if "mask" in name or "cutout" in name or "alpha" in name:
            v = disc.astype(np.float32)
        elif "shadow" in name or "hard" in name:
            v = shadow.astype(np.float32)
        elif "height" in name or "dist" in name or "ph" in name:
            v = height
        else:                                    # gradients and anything else: small smooth values
            v = (0.1 * np.sin(xx / 17.0) * np.cos(yy / 23.0)).astype(np.float32)
        out[name] = v + rng.normal(0, 1e-3, v.shape).astype(np.float32)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", default=str(ROOT / "nodes" / "weights" / "ssnpp.pt"))
    ap.add_argument("--runs", type=int, default=21)
    ap.add_argument("--size", type=int, default=256)
    a = ap.parse_args(argv)
    from pixgraph_nodes.ops import ssn
    model = ssn.load_model(a.weights)
    buffers = scene_buffers(model.config.channels, a.size)
    devices = ["cpu"] + (["cuda"] if torch.cuda.is_available() else [])
    from _machine import cpu_model              # benchmarks/ (on sys.path when run as a script)
    cuda = torch.cuda.get_device_name(0) if torch.cuda.is_available() else "none"
    print(f"{cpu_model()}; torch {torch.__version__}; CUDA: {cuda}; "
          f"CPU threads for inference {ssn.inference_threads()}; input {a.size}^2, channels {model.config.channels}")
    ref = None
    for dev in devices:
        os.environ[ssn.DEVICE_ENV] = dev
        chosen = ssn.inference_device()
        out = None
        for _ in range(2):
            out = ssn.predict(model, buffers, 2.0)
        times = []
        for _ in range(a.runs):
            if chosen.type == "cuda":
                torch.cuda.synchronize()
            t0 = time.perf_counter()
            out = ssn.predict(model, buffers, 2.0)       # returns on the CPU: includes the copies
            times.append((time.perf_counter() - t0) * 1e3)
        if ref is None:
            ref = out
        diff = float(np.abs(out - ref).max())
        print(f"{dev:5s} (inference_device {chosen}): median {statistics.median(times):.2f} ms, "
              f"min {min(times):.2f} ms over {a.runs} runs; darkness mean {out.mean():.4f}, "
              f"max |diff from cpu| {diff:.2e}")
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT / "benchmarks"))
    raise SystemExit(main())
