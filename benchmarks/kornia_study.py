"""Would kornia replace SSN++'s hand-written torch image code? Numbers and time.

    python benchmarks/kornia_study.py [--repeats 30]

Compares, on one torch thread, what kornia offers for the three places:
  1. nodes/ops/ssn.py: the bilinear resize to and from the network's 256^2 window
     (F.interpolate) vs kornia.geometry.transform.resize;
  2. lab/ssn/train.py: the SSIM term of the training loss (11-tap Gaussian window,
     zero padded as the benchmark's metric) vs kornia.metrics.ssim;
  3. the cost of importing kornia (paid by the node's first run in a process).
The training augmentation (a per-sample horizontal flip that also negates the
background's x-gradient channel) has no kornia counterpart shorter than itself.
"""
from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

import torch
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import cpu_model  # noqa: E402


def _median_ms(f, n):
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        f()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts) * 1e3


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=30)
    args = ap.parse_args()
    torch.set_num_threads(1)
    imports = []
    for _ in range(3):
        out = subprocess.run([sys.executable, "-c", "import time, torch; t = time.perf_counter(); import kornia; "
                              "print(time.perf_counter() - t)"], capture_output=True, text=True, check=True)
        imports.append(float(out.stdout) * 1e3)
    import kornia
    from pixgraph_lab.ssn import train as T

    torch.manual_seed(0)
    x = torch.rand(1, 6, 512, 512)
    a = F.interpolate(x, size=(256, 256), mode="bilinear", align_corners=False)
    b = kornia.geometry.transform.resize(x, (256, 256), interpolation="bilinear", align_corners=False)
    p = torch.rand(8, 1, 128, 128)
    g = (p + 0.1 * torch.rand(8, 1, 128, 128)).clamp(0, 1)
    taps = T._gauss_taps()
    s_hand, s_k = T.ssim_map(p, g, taps), kornia.metrics.ssim(p, g, 11, max_val=1.0)
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.1f}; one torch thread; "
          f"median of {args.repeats}")
    print(f"resize 6x512^2 -> 256^2: F.interpolate {_median_ms(lambda: F.interpolate(x, size=(256, 256), mode='bilinear', align_corners=False), args.repeats):.2f} ms, "
          f"kornia {_median_ms(lambda: kornia.geometry.transform.resize(x, (256, 256), interpolation='bilinear', align_corners=False), args.repeats):.2f} ms, "
          f"max |diff| {float((a - b).abs().max()):.2g}")
    print(f"SSIM 8x128^2: hand-written {_median_ms(lambda: T.ssim_map(p, g, taps), args.repeats):.1f} ms, "
          f"kornia {_median_ms(lambda: kornia.metrics.ssim(p, g, 11, max_val=1.0), args.repeats):.1f} ms, "
          f"max |diff| interior {float((s_hand - s_k)[..., 5:-5, 5:-5].abs().max()):.2g}, "
          f"border {float((s_hand - s_k).abs().max()):.2g} (kornia pads by reflection, the benchmark's metric by zeros)")
    print(f"import kornia after torch: {statistics.median(imports):.0f} ms (runs: "
          + ", ".join(f"{t:.0f}" for t in imports) + ")")


if __name__ == "__main__":
    main()
