"""Compare trained SSN++ runs on their shared validation split (not the benchmarks).

    python -m pixgraph_lab.ssn.compare_runs --data data/ssn_train2 runs/v2_plain runs/v2_struct

The validation split is the one ``train.py`` holds out when no ``--val`` is given
(``train.split_indices``: 5 % of the prepared samples, permutation seeded 1234), so a choice between runs
made here never looks at the benchmarks' test split. For each run: RMSE and the
benchmark's SSIM (``pixgraph_lab.metrics``, over counted pixels: outside the
cutout) per sample, averaged, on the whole 256² frame.
"""
from __future__ import annotations

import argparse
import pathlib

import numpy as np
import torch

from pixgraph_lab.metrics import rmse, ssim
from pixgraph_nodes.ops import ssn

from .train import split_indices


def val_split(folder: pathlib.Path, variant: str = "ssnpp"):
    """(x, softness, target, weight) of the held-out samples, read shard by shard."""
    files = sorted(folder.glob("*.npz"))
    sizes = []
    for f in files:
        with np.load(f) as z:
            sizes.append(len(z["softness"]))
    n = sum(sizes)
    want = set(split_indices(n)[0].tolist())
    xs, ss, ts, ws = [], [], [], []
    at = 0
    for f, k in zip(files, sizes):
        pick = [i - at for i in range(at, at + k) if i in want]
        if pick:
            with np.load(f) as z:
                names = [str(c) for c in z["channels"]]
                idx = [names.index(c) for c in ssn.VARIANTS[variant]]
                xs.append(z["x"][pick][:, idx].astype(np.float32))
                ss.append(z["softness"][pick])
                ts.append(z["target"][pick].astype(np.float32))
                ws.append(z["weight"][pick].astype(bool))
        at += k
    return np.concatenate(xs), np.concatenate(ss), np.concatenate(ts), np.concatenate(ws)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, type=pathlib.Path)
    ap.add_argument("runs", nargs="+", type=pathlib.Path)
    a = ap.parse_args(argv)
    x, s, t, w = val_split(a.data)
    print(f"{len(x)} validation samples of {a.data}\n")
    print("| run | steps | RMSE | SSIM |\n|---|---|---|---|")
    torch.set_num_threads(2)
    for run in a.runs:
        model = ssn.load_model(run / "model.pt")
        meta = torch.load(run / "model.pt", weights_only=True).get("meta", {})
        r, q = [], []
        with torch.no_grad():
            for i in range(len(x)):
                p = model(torch.from_numpy(x[i:i + 1]).contiguous(memory_format=torch.channels_last),
                          torch.from_numpy(s[i:i + 1]))[0, 0].numpy()
                p = np.clip(p, 0, 1)
                r.append(rmse(p, t[i], w[i]))
                q.append(ssim(p, t[i], w[i]))
        print(f"| {run} | {meta.get('steps', '?')} | {np.mean(r):.4f} | {np.mean(q):.4f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
