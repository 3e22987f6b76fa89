"""Write the tests' tiny held-out cutouts (tests/fixtures/height_heldout.npz).

    python -m pixgraph_lab.height.fixture --data data/height/test --out tests/fixtures/height_heldout.npz

Rule (fixed before looking at any prediction): from the test split (objects
never seen in training), in index order, the first ``--per-pose`` samples of
each pose (upright, tilted, lying, random); each cropped to its cutout's
bounding box plus 6 px and halved in size (2x2 box filter; pixel heights
halved, as a pixel height is a length in pixels).
"""
from __future__ import annotations

import argparse
import glob
import json
import os

import numpy as np


def shrink(a, k=2):
    H, W = a.shape[:2]
    a = a[: H // k * k, : W // k * k]
    return a.reshape(H // k, k, W // k, k, *a.shape[2:]).mean((1, 3))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--per-pose", type=int, default=2)
    ap.add_argument("--first", type=int, default=0,
                    help="instead: the first N samples in index order, whatever their pose "
                         "(tests/fixtures/height_real_heldout.npz: the real-cutout test split)")
    a = ap.parse_args(argv)
    want = {p: a.per_pose for p in ("upright", "tilted", "lying", "random")}
    first = a.first
    out = {}
    for f in sorted(glob.glob(os.path.join(a.data, "[0-9]" * 5 + ".npz"))):
        with np.load(f) as z:
            meta = json.loads(str(z["meta"]))
            if first:
                first -= 1
                if first == 0:
                    want = {}
            elif want.get(meta["pose"], 0) == 0:
                continue
            else:
                want[meta["pose"]] -= 1
            rows, cols = np.nonzero(z["mask"])
            r0, r1 = max(rows.min() - 6, 0), rows.max() + 7
            c0, c1 = max(cols.min() - 6, 0), cols.max() + 7
            rgb = z["rgb"][r0:r1, c0:c1].astype(np.float32)
            alpha = z["alpha"][r0:r1, c0:c1].astype(np.float32)
            h = z["height"][r0:r1, c0:c1].astype(np.float32) * z["mask"][r0:r1, c0:c1]
            m = z["mask"][r0:r1, c0:c1].astype(np.float32)
        k = f"s{meta['index']:05d}"
        # straight colour: average premultiplied, then divide (no dark fringe)
        a2 = shrink(alpha / 255)
        prem = shrink(rgb / 255 * (alpha / 255)[..., None])
        out[k + "_rgb"] = np.round(np.where(a2[..., None] > 0, prem / np.maximum(a2, 1e-6)[..., None], 0) * 255
                                   ).astype(np.uint8)
        out[k + "_alpha"] = np.round(a2 * 255).astype(np.uint8)
        m2 = shrink(m)
        out[k + "_mask"] = m2 > 0.99                      # fully covered half-res pixels
        out[k + "_height"] = (shrink(h) / np.maximum(m2, 1e-6) * 0.5 * (m2 > 0.99)).astype(np.float16)
        out[k + "_meta"] = np.array(json.dumps({"object": meta["object"], "pose": meta["pose"],
                                                "category": meta.get("category"),
                                                "index": meta["index"], "source": f}))
        if not any(want.values()):
            break
    np.savez_compressed(a.out, **out)
    print(f"{len(out) // 5} samples, {os.path.getsize(a.out)} bytes -> {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
