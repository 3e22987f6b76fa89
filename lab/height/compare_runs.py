"""Compare trained cutout-height runs on the validation splits (never the test split).

    python -m pixgraph_lab.height.compare_runs --data data/height --split val --split val_bench \
        nodes/weights/cutout_height.pt runs/height3/best.pt

For each checkpoint and each validation sub-folder of ``--data`` (objects unseen
in training: ``val`` from ``generate``, ``val_bench`` from ``from_benchmark``):
the pixel-height MAE [px] as ``train.evaluate`` computes it (per sample over the
crop's mask, averaged), and the contact-line heuristic's on the same samples.
The last column is the mean over the splits, each split weighted equally.
"""
from __future__ import annotations

import argparse

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.compare_runs", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", action="append", required=True)
    ap.add_argument("checkpoints", nargs="+")
    a = ap.parse_args(argv)
    import torch
    torch.set_num_threads(1)
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor

    from .train import evaluate, load_split
    cols = " | ".join(f"{s} MAE px" for s in a.split)
    print(f"| checkpoint | size | params | {cols} | mean |\n|---|---|---|" + "---|" * (len(a.split) + 1))
    heur, splits = {}, {}                      # splits: (name, size) -> arrays, loaded once
    for path in a.checkpoints:
        pred = LearnedHeightPredictor(path)
        maes = []
        for s in a.split:
            if (s, pred.size) not in splits:
                splits[s, pred.size] = load_split(a.data, s, pred.size)
            val = splits[s, pred.size]
            mae, hmae = evaluate(pred.model, val, pred.device)
            pred.model.eval()
            heur.setdefault(s, hmae)
            maes.append(mae)
        n = sum(p.numel() for p in pred.model.parameters())
        print(f"| {path} | {pred.size} | {n:,} | " + " | ".join(f"{m:.2f}" for m in maes)
              + f" | {np.mean(maes):.2f} |")
    print("| contact line (heuristic) | | | " + " | ".join(f"{heur[s]:.2f}" for s in a.split)
          + f" | {np.mean([heur[s] for s in a.split]):.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
