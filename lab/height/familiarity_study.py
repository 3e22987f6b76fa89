"""Does the network's own feature space know an unfamiliar shape? (docs/height-record.md,
"Measured: a familiarity signal from the network's features", ninth session).

    python -m pixgraph_lab.height.familiarity_study --data data/hsnap \\
        --heights data/hreal/val data/hreal/val_heldout

The shipped confidence is too high on kinds the model was not trained on, and no
signal of ``learned_height.confidence_signals`` tells such a cutout from a familiar
one. The usual out-of-distribution test is a distance in the network's feature
space: here the encoder's last two levels (``HeightNet.encode``: the 8^2 and 4^2
maps of a 64^2 crop), averaged over space, of

* a *bank*: ``--per-split`` crops (seed 0) of each training split's crop cache
  (``data/hsnap/cache_S_64.npz``, ``--train-splits``), standardised per feature;
* every sample of the ``--heights`` folders, prepared exactly as the predictor
  prepares a cutout (``learned_height.prepare``).

Each distance is scored two ways: the AUC with which it tells the *last*
``--heights`` folder (the unfamiliar kinds) from the others, and its Spearman
correlation, per folder, with the per-sample gain ``MAE(learned) - MAE(contact
line)`` [px] (the target of ``confidence_study``). A useful familiarity signal has
an AUC well above 0.5 and a positive correlation on the unfamiliar kinds; the
shipped rule's signal is printed for comparison. Nothing is chosen or written.
"""
from __future__ import annotations

import argparse
import os

import numpy as np
from scipy.stats import rankdata


def auc(positive, score) -> float:
    """The probability that a random positive sample scores above a random negative
    one (ties count a half): the Mann-Whitney U over n_pos n_neg."""
    y = np.asarray(positive, bool)
    r = rankdata(np.asarray(score, float))
    n1, n0 = int(y.sum()), int((~y).sum())
    return float((r[y].sum() - n1 * (n1 + 1) / 2) / (n0 * n1))


def pooled_features(net, x: np.ndarray, levels: int = 2) -> np.ndarray:
    """(N, 6, S, S) crops -> (N, C) the spatial means of the encoder's last ``levels`` levels."""
    return np.concatenate([f.mean((1, 2)) for f in net.encode(x)[-levels:]], axis=1)


def distances(bank: np.ndarray, feats: np.ndarray, k: int = 10, pca: int = 10) -> dict:
    """Per sample of ``feats``, its distances to the ``bank`` (both (N, C)), after
    standardising every feature by the bank's mean and std:

    * ``knn1`` / ``knn10``: to the nearest / mean of the ``k`` nearest bank rows;
    * ``cos_knn10``: 1 - the mean cosine similarity of the ``k`` most similar rows
      (unstandardised features);
    * ``maha10``: Mahalanobis in the bank's first ``pca`` principal components;
    * ``pca_residual10``: the length of what those components leave out."""
    mu, sd = bank.mean(0), bank.std(0) + 1e-6
    zb, zf = (bank - mu) / sd, (feats - mu) / sd
    d2 = (zf ** 2).sum(1)[:, None] + (zb ** 2).sum(1)[None] - 2 * zf @ zb.T
    d = np.sort(np.sqrt(np.maximum(d2, 0.0)), axis=1)
    nb = bank / np.linalg.norm(bank, axis=1, keepdims=True)
    nf = feats / np.linalg.norm(feats, axis=1, keepdims=True)
    cos = -np.sort(-(nf @ nb.T), axis=1)
    _, s, vt = np.linalg.svd(zb, full_matrices=False)        # zb has mean 0
    proj = zf @ vt[:pca].T
    resid = zf - proj @ vt[:pca]
    return {"knn1": d[:, 0], f"knn{k}": d[:, :k].mean(1), f"cos_knn{k}": 1.0 - cos[:, :k].mean(1),
            f"maha{pca}": np.sqrt(((proj / (s[:pca] / np.sqrt(len(zb)))) ** 2).sum(1)),
            f"pca_residual{pca}": np.linalg.norm(resid, axis=1)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.familiarity_study",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--weights", default=None, help="the checkpoint (default: the shipped one)")
    ap.add_argument("--data", required=True, help="the folder of the training crop caches (cache_S_64.npz)")
    ap.add_argument("--train-splits", default="train,train_organic,train3,train_flat,train_assembly")
    ap.add_argument("--per-split", type=int, default=400)
    ap.add_argument("--heights", nargs="+", required=True,
                    help="sample folders; the last holds the unfamiliar kinds")
    args = ap.parse_args(argv)

    from pixgraph_nodes.ops.learned_height import (LearnedHeightPredictor, contact_line_height, prepare,
                                                   straight_srgb)
    from .confidence_study import spearman
    from .evaluate import height_files, read_height_sample
    pred = LearnedHeightPredictor(**({"path": args.weights} if args.weights else {}), backend="numpy")
    rng = np.random.default_rng(0)
    bank = []
    for split in args.train_splits.split(","):
        with np.load(os.path.join(args.data, f"cache_{split}_{pred.size}.npz")) as z:
            x = z["x"]
            idx = np.sort(rng.choice(len(x), min(args.per_split, len(x)), replace=False))
            for i in range(0, len(idx), 50):
                bank.append(pooled_features(pred.net, x[idx[i:i + 50]].astype(np.float32)))
    bank = np.concatenate(bank)
    folder, gain, rule_signal, feats = [], [], [], []
    for d in args.heights:
        for f in height_files(d):
            _, rgba, true, mask = read_height_sample(f)
            r = pred.predict_full(rgba)
            gain.append(float(np.abs(r["height"] - true)[mask].mean() - np.abs(r["heuristic"] - true)[mask].mean()))
            rule_signal.append(r.get("signal", np.nan))
            colour, alpha = straight_srgb(rgba)
            x, _, _ = prepare(colour, alpha, pred.size, contact_line=contact_line_height(alpha > 0.5))
            feats.append(pooled_features(pred.net, x[None])[0])
            folder.append(d)
    folder, gain = np.array(folder), np.array(gain)
    scores = distances(bank, np.stack(feats))
    scores["shipped rule's signal"] = np.array(rule_signal, float)
    unfamiliar = folder == args.heights[-1]
    names = [os.path.basename(os.path.normpath(d)) for d in args.heights]
    print(f"bank: {len(bank)} training crops x {bank.shape[1]} features; samples: "
          + ", ".join(f"{n} {int((folder == d).sum())}" for n, d in zip(names, args.heights)))
    print(f"{'distance':24s} {'AUC ' + names[-1]:>22s}  " + "  ".join(f"{'rho ' + n:>18s}" for n in names))
    for name, s in scores.items():
        rhos = "  ".join(f"{spearman(s[folder == d], gain[folder == d]):>+18.3f}" for d in args.heights)
        print(f"{name:24s} {auc(unfamiliar, s):>22.3f}  {rhos}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
