"""Independent branches at once: does ``Session(workers=N)`` pay on this machine?

    python benchmarks/engine_concurrency.py [--branches 4] [--size 1024] [--repeats 5]

A source feeds ``--branches`` independent host nodes (each a numpy FFT blur of a
``size``² image, which releases the GIL) joined by a sum. Each row is the median
wall time of a cold run (fresh session) with 1, 2 and --branches workers, and
the speed-up over 1. The OpenCL device is shared, so device nodes take turns
(``scheduler.DeviceGate``): only host work (numpy, torch) can overlap.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import cpu_model  # noqa: E402

from pixgraph import types as T  # noqa: E402
from pixgraph.node import Node, node, param, port  # noqa: E402
from pixgraph.registry import Registry  # noqa: E402
from pixgraph.session import Session  # noqa: E402


class Array(T.PortType):
    """float32 (H, W) array."""


@node("bench.Source", version=1)
class Source(Node):
    """A reproducible noise image."""
    class Params:
        size: int = param(1024, min=1)
    class Outputs:
        out: Array = port()

    def compute(self, ctx, inputs, params):
        return {"out": np.random.default_rng(0).random((params.size, params.size), dtype=np.float32)}


@node("bench.FFTBlur", version=1)
class FFTBlur(Node):
    """Gaussian blur through the FFT (numpy releases the GIL inside)."""
    class Inputs:
        x: Array = port()
    class Params:
        sigma: float = param(3.0)
    class Outputs:
        out: Array = port()

    def compute(self, ctx, inputs, params):
        h, w = inputs.x.shape
        fy, fx = np.fft.fftfreq(h)[:, None], np.fft.rfftfreq(w)[None, :]
        g = np.exp(-2 * (np.pi * params.sigma) ** 2 * (fx * fx + fy * fy))
        out = inputs.x
        for _ in range(3):
            out = np.fft.irfft2(np.fft.rfft2(out) * g, s=(h, w))
        return {"out": out.astype(np.float32)}


@node("bench.Sum", version=1)
class Sum(Node):
    """Sum of up to 8 arrays."""
    class Inputs:
        a: Array = port()
        b: Array = port(optional=True)
        c: Array = port(optional=True)
        d: Array = port(optional=True)
        e: Array = port(optional=True)
        f: Array = port(optional=True)
        g: Array = port(optional=True)
        h: Array = port(optional=True)
    class Outputs:
        out: Array = port()

    def compute(self, ctx, inputs, params):
        return {"out": sum(v for v in inputs.values() if v is not None).astype(np.float32)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--branches", type=int, default=4, choices=range(2, 9))
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    reg = Registry()
    for cls in (Source, FFTBlur, Sum):
        reg.add(cls, source="benchmark")
    workers_list = sorted({1, 2, args.branches})
    times = {w: [] for w in workers_list}
    ref = None
    for _ in range(args.repeats):
        for w in workers_list:
            s = Session(registry=reg, workers=w)
            b = s.builder()
            b.add("bench.Source", "src", size=args.size)
            b.add("bench.Sum", "sum")
            for i in range(args.branches):
                b.add("bench.FFTBlur", f"blur{i}", sigma=1.0 + i)
                b.connect("src.out", f"blur{i}.x")
                b.connect(f"blur{i}.out", f"sum.{'abcdefgh'[i]}")
            b.output("o", "sum.out")
            g = b.build()
            t0 = time.perf_counter()
            out = s.run(g)["o"]
            times[w].append(time.perf_counter() - t0)
            ref = out if ref is None else ref
            assert np.array_equal(out, ref), "results differ between worker counts"
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.1f}")
    print(f"{args.branches} branches of a {args.size}^2 FFT blur, median of {args.repeats} cold runs\n")
    base = statistics.median(times[1])
    print(f"{'workers':>8}{'median s':>10}{'speed-up':>10}")
    for w in workers_list:
        med = statistics.median(times[w])
        print(f"{w:>8}{med:10.3f}{base / med:10.2f}")


if __name__ == "__main__":
    main()
