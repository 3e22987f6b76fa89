"""Turn ground-truth samples into SSN++ training shards.

    python -m pixgraph_lab.ssn.prepare data/wall_train data/ground_train --out data/ssn_train

For every sample of the ground-truth generator (``pixgraph_lab.datagen``) this
computes the buffer channels with *our* pixel-height tracer from the sample's
cutout mask, cutout and background pixel heights and its disk light (centre and 4
extreme points through the sample's camera), exactly as the SSN++ node will at
run time, and pairs them with the renderer's soft shadow.

Shard format (``shard_NNN.npz``): ``x`` (N, 9, H, W) float16 network inputs in
``ssn.VARIANTS["ssnpp"]`` order, already normalised by ``ssn.stack_channels``;
``softness`` (N,) float32 = light radius / distance to the object;
``target`` (N, H, W) float16 ground-truth darkness; ``weight`` (N, H, W) uint8, 1
where the loss counts (outside the cutout, on valid background);
``channels`` the channel names; ``ids`` the source sample paths.
"""
from __future__ import annotations

import argparse
import json
import pathlib

import numpy as np
from tqdm import tqdm

from pixgraph.device import Device
from pixgraph_nodes.ops import ssn
from pixgraph_nodes.ops.buffers import buffer_channels
from pixgraph_nodes.ops.lights import Light, disk_extremes, light_point
from pixgraph_lab.datagen.dataset import load_sample, sample_files


def sample_light(sample: dict) -> Light:
    """The sample's disk light as a ``Light`` value."""
    return Light("disk", position=tuple(map(float, sample["light_center"])),
                 radius=float(sample["light_radius"]),
                 normal=tuple(map(float, sample["light_normal"])))


def softness(sample: dict) -> float:
    """The light's softness exactly as ``pixgraph.SoftShadowSSN`` computes it at run
    time (``ssn.softness_of``): disk radius over the distance from the light's
    centre to the mean of the cutout's reconstructed 3D points (dimensionless).

    The first training set used the generator's ``relative_radius`` instead
    (radius over the distance to the centre of the object's 3D bounding box,
    including parts the camera cannot see), which is not what the node can know.
    """
    return ssn.softness_of(sample_light(sample), sample["camera"], sample["mask"],
                           np.where(sample["mask"], sample["fg_height"], 0.0))


def sample_inputs(device, sample: dict, thickness: float = 1.0):
    """(buffers dict, softness, weight mask) of one ground-truth sample."""
    cam = sample["camera"]
    light = sample_light(sample)
    mask = sample["mask"].astype(np.float32)
    fg = np.where(sample["mask"], sample["fg_height"], 0.0).astype(np.float32)
    bg = np.nan_to_num(sample["bg_height"].astype(np.float32), nan=0.0)
    buffers = buffer_channels(device, mask, fg, bg, light_point(light, cam), disk_extremes(light, cam),
                              thickness=thickness)
    weight = (~sample["mask"]) & sample["bg_valid"]
    return buffers, softness(sample), weight


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sources", nargs="+", type=pathlib.Path, help="ground-truth sample folders")
    ap.add_argument("--out", required=True, type=pathlib.Path)
    ap.add_argument("--shard", type=int, default=200, help="samples per shard")
    ap.add_argument("--device", default=None)
    a = ap.parse_args(argv)
    device = Device.open(a.device)
    files = [f for src in a.sources for f in sample_files(str(src))]
    a.out.mkdir(parents=True, exist_ok=True)
    chans = ssn.VARIANTS["ssnpp"]
    batch: dict[str, list] = {"x": [], "softness": [], "target": [], "weight": [], "ids": []}
    nshard = 0

    def flush():
        nonlocal nshard
        if not batch["x"]:
            return
        np.savez(a.out / f"shard_{nshard:03d}.npz", x=np.stack(batch["x"]).astype(np.float16),
                 softness=np.array(batch["softness"], np.float32),
                 target=np.stack(batch["target"]).astype(np.float16),
                 weight=np.stack(batch["weight"]).astype(np.uint8),
                 channels=np.array(chans), ids=np.array(batch["ids"]))
        nshard += 1
        for v in batch.values():
            v.clear()

    for f in tqdm(files, desc="prepare"):
        s = load_sample(f)
        buffers, soft, weight = sample_inputs(device, s)
        batch["x"].append(ssn.stack_channels(buffers, chans))
        batch["softness"].append(soft)
        batch["target"].append(s["shadow"])
        batch["weight"].append(weight)
        batch["ids"].append(f)
        if len(batch["x"]) >= a.shard:
            flush()
    flush()
    (a.out / "info.json").write_text(json.dumps(
        {"sources": [str(s) for s in a.sources], "samples": len(files), "channels": list(chans)}, indent=1) + "\n")
    print(f"{len(files)} samples -> {nshard} shards in {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
