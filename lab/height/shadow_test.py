"""Ground-truth shadow benchmark of the held-out named meshes (for the height predictor's shadow goals).

    python -m pixgraph_lab.height.shadow_test --benchmark wall --n 60 --seed 0 --light-samples 64 \
        --out data/hreal/wall_named64

The ground-truth renderer of ``pixgraph_lab.datagen.generate`` (same scenes,
walls, lights, soft shadows; test-split backgrounds) with its object replaced
by one of pybullet_data's named meshes (``pixgraph_lab.height.real.NAMED``: duck,
teddy, bunny, mug, table, lego, soccer ball, torus, tray), posed like the
height test split (``real.pose_real``: upright 80 %, tilted 10 %, lying 6 %,
random 4 %) and scaled to 0.4-1.6 camera heights. These meshes are never in
training or validation. Files are in the benchmark's own format (``dataset``),
so ``pixgraph_lab.evaluate.prepared_sample`` reads them. Sample ``i`` depends only
on ``(seed, benchmark, i)``; existing files are skipped (resumable).
"""
from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time

import numpy as np

SEED_OFFSET = 9100   # keeps these scenes' random streams apart from the benchmark's own test split


def load_named(obj_id: str, rng: np.random.Generator):
    """(V, F) of a named mesh posed as the module doc says, resting on Y = 0."""
    from .real import REAL_POSE_P, REAL_POSES, named_mesh, pose_real
    V0, F = named_mesh(obj_id)
    pose = str(rng.choice(REAL_POSES, p=REAL_POSE_P))
    return pose_real(V0, pose, rng, height_range=(0.4, 1.6)), F


@contextlib.contextmanager
def named_objects():
    """Swap the benchmark generator's object choice for the named meshes (restored after)."""
    from pixgraph_lab.datagen import generate as g

    from .real import NAMED
    old = g.choose_object, g.load_object
    ids = list(NAMED)
    g.choose_object = lambda split, rng, mix=1, **k: ids[rng.integers(len(ids))]
    g.load_object = load_named
    try:
        yield
    finally:
        g.choose_object, g.load_object = old


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.shadow_test", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--benchmark", choices=("wall", "ground"), default="wall")
    ap.add_argument("--n", type=int, required=True)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--light-samples", type=int, default=64)
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    from pixgraph_lab.datagen.dataset import sample_path, save_sample
    from pixgraph_lab.datagen.generate import make_sample, write_index
    from pixgraph_lab.datagen.raycast import select_variant
    variant = select_variant()
    os.makedirs(a.out, exist_ok=True)
    config = {"benchmark": a.benchmark, "split": "test", "n": a.n, "start": a.start, "seed": a.seed,
              "res": a.res, "light_samples": a.light_samples, "objects": "pybullet_data named meshes",
              "mitsuba_variant": variant,
              "command": " ".join(["python -m pixgraph_lab.height.shadow_test"] + (argv or sys.argv[1:]))}
    t0, made = time.perf_counter(), 0
    with named_objects():
        for i in range(a.start, a.start + a.n):
            p = sample_path(a.out, i)
            if os.path.exists(p):
                continue
            arrays, meta = make_sample(a.benchmark, "test", i, a.seed + SEED_OFFSET, a.res, a.light_samples)
            save_sample(p, arrays, meta)
            made += 1
            if made % 10 == 0:
                write_index(a.out, config, a.n)
                print(f"{made} new, {(time.perf_counter() - t0) / made:.1f} s/sample", flush=True)
    write_index(a.out, config, a.n)
    print(f"{made} new samples in {time.perf_counter() - t0:.0f} s in {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
