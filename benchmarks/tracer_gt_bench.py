"""The pixel-height tracer against ray-traced ground truth, this checkout against an
earlier commit's tracer (``nodes/ops/shadow.py``, ``shadow.cl``, ``march.py``,
``march.h`` taken from git), on generated benchmark scenes:

    python -m pixgraph_lab.datagen.generate --benchmark wall --split test --n 40 --seed 0 --mix 2 --out out/gt/wall
    python -m pixgraph_lab.datagen.generate --benchmark ground --split test --n 40 --seed 0 --mix 2 --out out/gt/ground
    python benchmarks/tracer_gt_bench.py --data out/gt/wall --data out/gt/ground --old e2fbdf3

For each scene: the hard shadow (light centre) and the soft shadow with 64 samples
(``lab/evaluate.py``'s ``hard`` and ``soft:64``, thickness 1 px), darkness RMSE
against the renderer's soft shadow over visible background pixels; printed: the
mean over the scenes of each, old and new, and how many pixels changed. Nothing
here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import importlib
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

from _machine import cpu_model

ROOT = pathlib.Path(__file__).resolve().parent.parent
FILES = ("shadow.py", "shadow.cl", "march.py", "march.h")


def old_module(commit: str, where: pathlib.Path):
    """The tracer of ``commit`` as an importable package ``old_ops`` under ``where``."""
    pkg = where / "old_ops"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    for f in FILES:
        text = subprocess.run(["git", "-C", str(ROOT), "show", f"{commit}:nodes/ops/{f}"], check=True,
                              capture_output=True, text=True).stdout
        (pkg / f).write_text(text)
    sys.path.insert(0, str(where))
    return importlib.import_module("old_ops.shadow")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", action="append", required=True)
    ap.add_argument("--old", required=True, help="commit whose tracer is compared")
    ap.add_argument("--samples", type=int, default=64)
    a = ap.parse_args()
    from pixgraph.device import Device
    from pixgraph_lab.datagen.dataset import sample_files
    from pixgraph_lab.evaluate import prepared_sample
    from pixgraph_nodes.ops import shadow as new
    from pixgraph_nodes.ops.lights import disk_samples, light_point
    dev = Device.open()
    print(f"# tracer vs ground truth, {a.old} -> this checkout; {cpu_model()}")
    print("| scenes | method | RMSE old | RMSE new | pixels changed |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        old = old_module(a.old, pathlib.Path(tmp))
        for data in a.data:
            files = sample_files(data)
            res = {"hard": [[], [], 0], f"soft:{a.samples}": [[], [], 0]}
            for f in files:
                s = prepared_sample(f, dev)
                valid = ~s["mask"] & s["bg_valid"]
                gt = s["shadow"].astype(np.float64)
                args = (s["mask"].astype(np.float32), s["fg_height"], s["bg_height"])
                for name, fn in (("hard", lambda mod: mod.hard_shadow(dev, *args, light_point(s["light"], s["camera"]),
                                                                      1.0)),
                                 (f"soft:{a.samples}", lambda mod: mod.soft_shadow(
                                     dev, *args, disk_samples(s["light"], s["camera"], a.samples), 1.0))):
                    d_old, d_new = 1.0 - fn(old), 1.0 - fn(new)
                    for k, d in enumerate((d_old, d_new)):
                        res[name][k].append(float(np.sqrt(np.mean((d.astype(np.float64) - gt)[valid] ** 2))))
                    res[name][2] += int((d_old != d_new).sum())
            for name, (o, n, changed) in res.items():
                print(f"| {data} ({len(files)}) | {name} | {np.mean(o):.5f} | {np.mean(n):.5f} | {changed} |",
                      flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
