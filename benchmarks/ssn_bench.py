"""SSN++ inference time at 256^2 on this machine (the issue's goal: <= 50 ms).

    python benchmarks/ssn_bench.py [--weights nodes/weights/ssnpp.pt] [--threads N] [--runs 21]

Reports the median (and min) over ``--runs`` after warm-up of: the network alone
(torch, CPU), the buffer channels (OpenCL), and the SoftShadowSSN node's whole
compute on the wall-corner example scene resized to 256^2; plus parameters and
FLOPs.

With ``--data`` it times evaluation methods (``pixgraph_lab.evaluate`` specs:
``soft:N``, ``module:function``) on the first ``--limit`` benchmark samples
instead, interleaved sample by sample, ``--runs`` times each; this is how the
ablation table's ms/sample and the classical soft shadow "at equal time" are
measured (the evaluator's own ms column is one run per sample)::

    python benchmarks/ssn_bench.py --data data/wall_test --limit 40 --runs 3 \
        --method soft:64 --method soft:128 \
        --method pixgraph_lab.ssn.methods:run_ssg --method pixgraph_lab.ssn.methods:run_ssnpp \
        --json out/ssn_bench.json

Nothing here is asserted by the tests.
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

from _machine import cpu_model

ROOT = pathlib.Path(__file__).resolve().parents[1]


def machine() -> str:
    return f"{cpu_model()}, torch {torch.__version__}, {torch.get_num_threads()} threads"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", default=str(ROOT / "nodes" / "weights" / "ssnpp.pt"))
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--runs", type=int, default=21)
    ap.add_argument("--data", help="benchmark sample folder: time --method specs on its samples")
    ap.add_argument("--limit", type=int, default=40, help="with --data: samples to use")
    ap.add_argument("--method", action="append", default=[], help="with --data: evaluation method spec")
    ap.add_argument("--json", help="with --data: write the timings here")
    a = ap.parse_args(argv)
    if a.threads:
        torch.set_num_threads(a.threads)
    if a.data:
        return time_methods(a)
    from pixgraph.device import Device
    from pixgraph.session import Session
    from pixgraph_nodes.ops import ssn
    from pixgraph_nodes.ops.buffers import buffer_channels
    from pixgraph_nodes.ops.lights import disk_extremes, light_point

    model = ssn.load_model(a.weights)
    print(machine())
    print(f"model {a.weights}: {ssn.count_params(model):,} parameters, "
          f"{ssn.count_flops(model) / 1e9:.2f} GFLOP per 256^2 sample")
    # the example scene's inputs, at 256^2
    import torch.nn.functional as F
    s = Session(disk_cache=None)
    full = s.run(ROOT / "graphs" / "ssn_wall_corner.yaml",
                 outputs=["cutout.alpha", "fg_h.height", "bg_h.height", "light.light", "cam.camera"])
    half = lambda x, scale=1.0: (F.interpolate(torch.from_numpy(np.array(x, dtype=np.float32))[None, None], size=(256, 256),
                                               mode="bilinear", align_corners=False)[0, 0].numpy() * scale)
    mask = (half(full["cutout.alpha"]) > 0.5).astype(np.float32)
    fg = (half(full["fg_h.height"], 0.5) * mask).astype(np.float32)
    bg = half(full["bg_h.height"], 0.5).astype(np.float32)
    cam = full["cam.camera"].scaled(0.5)
    light = full["light.light"]
    dev = Device.open()
    lp, le = light_point(light, cam), disk_extremes(light, cam)
    buffers = buffer_channels(dev, mask, fg, bg, lp, le)
    x = torch.from_numpy(ssn.stack_channels(buffers, model.config.channels))[None]
    soft = torch.tensor([ssn.softness_of(light, cam, mask, fg)])
    tdev = ssn.inference_device()           # the node's: PIXGRAPH_TORCH_DEVICE, else CUDA when torch has it
    net, xd, sd = ssn.model_on(model, tdev), x.to(tdev), soft.to(tdev)
    cases = {
        # .cpu(): the result back on the host, as the node needs it (and a CUDA run waits for it)
        "network alone (torch)": lambda: net(xd, sd).cpu(),
        "buffer channels (OpenCL)": lambda: buffer_channels(dev, mask, fg, bg, lp, le),
        "whole SSN++ prediction": lambda: ssn.predict(model, buffer_channels(dev, mask, fg, bg, lp, le), float(soft)),
    }
    # interleave the cases round by round, so a slow spell of the machine
    # (or PoCL's worker threads winding down) does not land on one case only
    times = {name: [] for name in cases}
    with torch.inference_mode():
        for fn in cases.values():
            fn()
        for _ in range(a.runs):
            for name, fn in cases.items():
                t = time.perf_counter()
                fn()
                times[name].append((time.perf_counter() - t) * 1000)
    rows = [(name, statistics.median(ts), min(ts)) for name, ts in times.items()]
    print(f"device: {dev.name}; torch: {tdev}")
    print(f"{'256^2':30s} {'median ms':>10s} {'min ms':>8s}")
    for name, med, mn in rows:
        print(f"{name:30s} {med:10.1f} {mn:8.1f}")
    return 0


def _torch_device() -> str:
    """Where SSN++ runs its network (``PIXGRAPH_TORCH_DEVICE``, default CUDA when torch has it)."""
    from pixgraph_nodes.ops import ssn
    return str(ssn.inference_device())


def time_methods(a) -> int:
    """Median ms per sample of each method on real benchmark samples."""
    import json
    from pixgraph.device import Device
    from pixgraph_lab.datagen.dataset import sample_files
    from pixgraph_lab.evaluate import Method, prepared_sample

    if not a.method:
        raise SystemExit("--data needs at least one --method")
    device = Device.open()
    methods = [Method(spec) for spec in a.method]
    samples = [prepared_sample(f, device) for f in sample_files(a.data)[:a.limit]]
    print(machine())
    print(f"device: {device.name}; torch: {_torch_device()}; {len(samples)} samples of {a.data}, {a.runs} runs each")
    times = {m.spec: [] for m in methods}
    for m in methods:                       # build programs, load weights
        m.predict(samples[0])
    for _ in range(a.runs):
        for s in samples:
            for m in methods:
                t = time.perf_counter()
                m.predict(s)
                times[m.spec].append((time.perf_counter() - t) * 1000)
    print(f"{'method':50s} {'median ms':>10s} {'p10 ms':>8s} {'p90 ms':>8s}")
    result = {"machine": machine(), "device": device.name, "torch_device": _torch_device(), "data": a.data, "samples": len(samples),
              "runs": a.runs, "ms": {}}
    for spec, ts in times.items():
        q = np.percentile(ts, [10, 50, 90])
        print(f"{spec:50s} {q[1]:10.1f} {q[0]:8.1f} {q[2]:8.1f}")
        result["ms"][spec] = {"median": float(q[1]), "p10": float(q[0]), "p90": float(q[2])}
    if a.json:
        pathlib.Path(a.json).parent.mkdir(parents=True, exist_ok=True)
        pathlib.Path(a.json).write_text(json.dumps(result, indent=2) + "\n")
        print(f"wrote {a.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
