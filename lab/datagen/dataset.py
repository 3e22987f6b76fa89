"""Reading ground-truth benchmarks (no Mitsuba needed). Format: docs/ground-truth.md."""
from __future__ import annotations

import glob
import json
import os

import numpy as np

from pixgraph_nodes.ops.camera import Camera

FORMAT_VERSION = 1


def sample_path(out_dir: str, index: int) -> str:
    return os.path.join(out_dir, f"{index:05d}.npz")


def save_sample(path: str, arrays: dict, meta: dict) -> None:
    """Write one sample atomically (temp file + rename: a kill never leaves half a file)."""
    tmp = path + ".tmp"
    with open(tmp, "wb") as fh:
        np.savez_compressed(fh, meta=np.array(json.dumps(meta)), **arrays)
    os.replace(tmp, path)


def load_sample(path: str) -> dict:
    """All arrays of a sample plus ``meta`` (dict) and ``camera`` (Camera)."""
    with np.load(path, allow_pickle=False) as z:
        out = {k: z[k] for k in z.files}
    out["meta"] = json.loads(str(out["meta"]))
    out["camera"] = Camera(**out["meta"]["scene"]["camera"])
    return out


def sample_files(data_dir: str) -> list[str]:
    files = sorted(glob.glob(os.path.join(data_dir, "[0-9]" * 5 + ".npz")))
    if not files:
        raise FileNotFoundError(f"no samples (NNNNN.npz) in {data_dir}")
    return files


def read_index(data_dir: str) -> dict:
    with open(os.path.join(data_dir, "index.json")) as fh:
        return json.load(fh)
