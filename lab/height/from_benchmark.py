"""Cutout samples for the pixel-height predictor from the ground-truth benchmarks' renders.

    python -m pixgraph_lab.height.from_benchmark --src data/wall_train2 --src data/ground_train2 \
        --out data/height

``pixgraph_lab.height.generate`` shades its cutouts with a preview shader; the
shadow benchmarks (``pixgraph_lab.datagen.generate``) render theirs with Mitsuba's
path tracer, other materials, other cameras and their own object mix (thin open
tables, chairs, frames; randomly rotated meshes). A predictor trained on one
renderer's look only learns that look, so this copies the cutout part of every
benchmark sample (colour, alpha, mask, the renderer's pixel height) into the
height-sample format of ``generate`` (``NNNNN.npz``: ``rgb`` uint8 sRGB straight
colour, ``alpha`` uint8, ``mask`` bool, ``height`` float16 [px], ``meta``).

Splits stay object-disjoint: each sample goes by its object's
``generate.height_split`` to ``OUT/train_bench`` or ``OUT/val_bench``; an object of
the height test split is an error (the benchmarks' *train* splits hold none). Use only benchmark *train* splits as sources: the test splits are
what the predictor is scored on. Output index = ``--start`` + the running count of
sources, so two sources never collide; existing files are skipped (resumable).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np


def convert(sample: dict) -> tuple[dict, dict]:
    """(arrays, meta) of one benchmark sample (``datagen.dataset.load_sample``) in the
    height-sample format."""
    from .generate import is_overhang, srgb_encode
    a = np.clip(np.asarray(sample["alpha"], np.float32), 0, 1)
    rgb = np.asarray(sample["rgb"], np.float32)                 # linear, straight
    mask = np.asarray(sample["mask"], bool)
    h = np.where(mask, np.asarray(sample["fg_height"], np.float32), 0.0)
    arrays = {"rgb": np.round(srgb_encode(rgb) * 255).astype(np.uint8),
              "alpha": np.round(a * 255).astype(np.uint8), "mask": mask, "height": h.astype(np.float16)}
    scene = sample["meta"]["scene"]
    meta = {"object": scene["object"], "pose": "benchmark", "overhang": bool(is_overhang(mask, h)),
            "camera": scene["camera"], "mask_px": int(mask.sum())}
    return arrays, meta


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.from_benchmark", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--src", action="append", required=True, help="benchmark folder (a train split)")
    ap.add_argument("--out", required=True, help="height data folder (gets train_bench/ and val_bench/)")
    ap.add_argument("--start", type=int, default=0, help="index of the first sample written")
    ap.add_argument("--min-pixels", type=int, default=64, help="skip cutouts smaller than this [px]")
    a = ap.parse_args(argv)
    from pixgraph_lab.datagen.dataset import load_sample, sample_files

    from .generate import height_split
    counts = {"train": 0, "val": 0, "skipped_small": 0}
    t0 = time.perf_counter()
    i = a.start
    for src in a.src:
        index = json.load(open(os.path.join(src, "index.json")))
        split_of_src = index.get("config", {}).get("split")
        if split_of_src != "train":
            raise SystemExit(f"{src}: a {split_of_src!r} split; only benchmark train splits may be used")
        for f in sample_files(src):
            s = load_sample(f)
            obj = s["meta"]["scene"]["object"]
            split = height_split(obj)
            if split == "test":
                raise SystemExit(f"{f}: object {obj} belongs to the height test split")
            p = os.path.join(a.out, f"{split}_bench", f"{i:05d}.npz")
            i += 1
            if int(s["mask"].sum()) < a.min_pixels:
                counts["skipped_small"] += 1
                continue
            counts[split] += 1
            if os.path.exists(p):
                continue
            arrays, meta = convert(s)
            meta.update(split=split, index=i - 1, source=f)
            os.makedirs(os.path.dirname(p), exist_ok=True)
            with open(p + ".tmp", "wb") as fh:
                np.savez_compressed(fh, meta=np.array(json.dumps(meta)), **arrays)
            os.replace(p + ".tmp", p)
    cfg = {"command": " ".join(["python -m pixgraph_lab.height.from_benchmark"] + (argv or sys.argv[1:])),
           "counts": counts, "seconds": round(time.perf_counter() - t0, 1)}
    for split in ("train", "val"):
        d = os.path.join(a.out, f"{split}_bench")
        if os.path.isdir(d):
            with open(os.path.join(d, f"config_{a.start}.json"), "w") as fh:
                json.dump(cfg, fh, indent=1)
    print(json.dumps(cfg))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
