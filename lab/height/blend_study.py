"""Choose auto's blend of the learned map and the contact line on validation
(docs/height-record.md, "Rules fixed before measuring (issue 24, fourth session, ...)").

    python -m pixgraph_lab.height.blend_study --weights runs/height7/best.pt \\
        --heights data/hreal/val data/hreal/val_organic --out runs/blend_study

Per sample (every file of the ``--heights`` folders, pooled): the learned map
(``LearnedHeightPredictor.predict_full``, ``contact="ground"``, the checkpoint's
pin, foot snap and confidence rule), the contact line under the same constraint,
the rule's signal, and the MAE [px] over the object's pixels of the blend
``w * learned + (1 - w) * contact line`` for every ``w`` in {0, 0.05, ..., 1}.

Two candidates: (G) one weight for every cutout; (B) one weight per bin of the
signal, the bins being the confidence rule's stored quintile edges; each weight
minimises the mean MAE of its samples (ties: the larger weight). Each is scored
by 5-fold out-of-fold mean MAE (fixed folds, seed 0); the lower is the
candidate. The ship rule: the candidate's out-of-fold MAE at most ``--bar``
(0.98) x the current auto's MAE (the learned map, or the contact line where the
signal is above the rule's threshold). On the fifth model the rule was not met
(docs/height-record.md, "Measured: auto's blend and large cutouts"), so ``CutoutHeight`` has no blend;
this study is how to try it again for another checkpoint. ``--apply W`` judges one
weight on other folders instead (docs/height-record.md, "Rules fixed before
measuring: auto's blend for unseen kinds").
"""
from __future__ import annotations

import argparse
import os

import numpy as np

from .confidence_study import bin_of

GRID = np.round(np.linspace(0.0, 1.0, 21), 2)


def fit_weights(mae: np.ndarray, bins: np.ndarray, n_bins: int) -> np.ndarray:
    """Per bin, the grid weight with the lowest mean MAE of the bin's samples
    (``mae``: (N, len(GRID)); ``bins``: (N,) bin index; a bin without samples: 1)."""
    out = np.ones(n_bins)
    for b in range(n_bins):
        sel = bins == b
        if sel.any():
            m = mae[sel].mean(0)
            out[b] = GRID[np.flatnonzero(m <= m.min() + 1e-12)[-1]]
    return out


def blend_mae(mae: np.ndarray, bins: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Each sample's MAE at its bin's weight."""
    col = np.searchsorted(GRID, weights[bins])
    return mae[np.arange(len(bins)), col]


def out_of_fold(mae: np.ndarray, bins: np.ndarray, n_bins: int, folds: int = 5, seed: int = 0) -> np.ndarray:
    """Each sample's MAE with weights fitted on the other folds."""
    idx = np.random.default_rng(seed).permutation(len(bins))
    out = np.empty(len(bins))
    for k in range(folds):
        te = idx[k::folds]
        tr = np.setdiff1d(idx, te)
        w = fit_weights(mae[tr], bins[tr], n_bins)
        out[te] = blend_mae(mae[te], bins[te], w)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.blend_study", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", required=True)
    ap.add_argument("--heights", required=True, nargs="+", help="validation folders, pooled")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--bar", type=float, default=0.98, help="ship if out-of-fold MAE <= bar x auto's")
    ap.add_argument("--apply", type=float, default=None,
                    help="judge one weight W of the learned map instead of fitting: auto's map against "
                         "W * learned + (1 - W) * contact line where auto keeps the learned map, per sample, "
                         "with the paired bootstrap interval of the difference")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    import torch
    torch.set_num_threads(1)
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor

    from .evaluate import _write, height_files, read_height_sample, write_report
    pred = LearnedHeightPredictor(a.weights)
    rule = pred.confidence_rule
    if not rule:
        raise SystemExit(f"{a.weights} has no confidence rule (run confidence_study --write first)")
    rows, maes = [], []
    for d in a.heights:
        for f in height_files(d, a.limit):
            meta, rgba, true, mask = read_height_sample(f)
            r = pred.predict_full(rgba)
            hl, hc, t = r["height"][mask], r["heuristic"][mask], true[mask]
            mae = np.array([np.abs(w * hl + (1 - w) * hc - t).mean() for w in GRID])
            maes.append(mae)
            rows.append({"folder": d, "index": meta["index"], "category": meta.get("category", "?"),
                         "signal": r["signal"], "use_learned": int(r["use_learned"]),
                         "mae_learned": mae[-1], "mae_heuristic": mae[0]})
    mae = np.array(maes)
    if a.apply is not None:
        return judge_weight(a, rows, mae)
    sig = np.array([r["signal"] for r in rows])
    edges = np.asarray(rule["bins"], float)
    cands = {"G": (np.zeros(len(rows), int), 1, []),
             "B": (bin_of(sig, edges), len(edges) + 1, edges.tolist())}
    auto = np.where([r["use_learned"] for r in rows], mae[:, -1], mae[:, 0])
    oof = {k: out_of_fold(mae, b, n) for k, (b, n, _) in cands.items()}
    best = min(oof, key=lambda k: oof[k].mean())
    met = oof[best].mean() <= a.bar * auto.mean()
    fitted = {k: fit_weights(mae, b, n) for k, (b, n, _) in cands.items()}
    for i, r in enumerate(rows):
        for k, (b, n, _) in cands.items():
            r[f"mae_blend_{k}"] = float(blend_mae(mae[i:i + 1], b[i:i + 1], fitted[k])[0])
            r[f"mae_oof_{k}"] = float(oof[k][i])
        r["mae_auto"] = float(auto[i])
    os.makedirs(a.out, exist_ok=True)
    _write(os.path.join(a.out, "blend.csv"), rows)
    lines = [f"weights {a.weights}; {len(rows)} samples of {', '.join(a.heights)}; signal "
             f"{rule['signal']} (bins {np.round(edges, 4).tolist()})", "",
             "| candidate | weights (learned) | MAE fitted on all | MAE out-of-fold |", "|---|---|---|---|"]
    for k in cands:
        lines.append(f"| {k} | {fitted[k].tolist()} | {blend_mae(mae, cands[k][0], fitted[k]).mean():.3f} | "
                     f"{oof[k].mean():.3f} |")
    lines += ["", f"learned {mae[:, -1].mean():.3f}, current auto {auto.mean():.3f}, contact line "
              f"{mae[:, 0].mean():.3f} px",
              f"candidate {best}: out-of-fold {oof[best].mean():.3f} vs {a.bar} x auto = "
              f"{a.bar * auto.mean():.3f}: rule {'MET' if met else 'NOT met'}", "",
              "| category | n | MAE learned | MAE auto | MAE blend (out-of-fold) | MAE contact line | "
              "learned < contact line | blend < contact line |", "|---|---|---|---|---|---|---|---|"]
    cats = ["all"] + sorted({r["category"] for r in rows})
    for c in cats:
        sel = np.array([c == "all" or r["category"] == c for r in rows])
        lines.append(f"| {c} | {sel.sum()} | {mae[sel, -1].mean():.2f} | {auto[sel].mean():.2f} | "
                     f"{oof[best][sel].mean():.2f} | {mae[sel, 0].mean():.2f} | "
                     f"{np.mean(mae[sel, -1] < mae[sel, 0]):.0%} | {np.mean(oof[best][sel] < mae[sel, 0]):.0%} |")
    write_report(a.out, "blend_study.md", lines)
    return 0


def judge_weight(a, rows, mae) -> int:
    """``--apply W``: per sample the MAE [px] of auto's map today (the learned map, or the
    contact line where auto falls back) and of the blend at ``W`` where auto keeps the
    learned map; their means, the paired 95 % bootstrap interval of blend - auto
    (``scale_study.interval``: 10,000 resamples, seed 0), per category; rows in ``--out``."""
    from .evaluate import _write, write_report
    from .scale_study import interval
    k = int(np.argmin(np.abs(GRID - a.apply)))
    if abs(GRID[k] - a.apply) > 1e-9:
        raise SystemExit(f"--apply {a.apply}: not on the grid {GRID.tolist()}")
    use = np.array([r["use_learned"] for r in rows], bool)
    auto = np.where(use, mae[:, -1], mae[:, 0])
    blend = np.where(use, mae[:, k], mae[:, 0])
    lo, hi = interval(blend - auto)
    mean = float((blend - auto).mean())
    for i, r in enumerate(rows):
        r.update(mae_auto=float(auto[i]), mae_blend=float(blend[i]))
    os.makedirs(a.out, exist_ok=True)
    _write(os.path.join(a.out, "blend_apply.csv"), rows)
    lines = [f"weights {a.weights}; {len(rows)} samples of {', '.join(a.heights)}; w = {GRID[k]}", "",
             f"auto {auto.mean():.3f} px, blend {blend.mean():.3f} px ({blend.mean() / auto.mean():.4f}x); "
             f"blend - auto {mean:+.3f} px, 95 % interval {lo:+.3f} to {hi:+.3f}", "",
             "| category | n | MAE auto | MAE blend | contact line |", "|---|---|---|---|---|"]
    for c in ["all"] + sorted({r["category"] for r in rows}):
        sel = np.array([c == "all" or r["category"] == c for r in rows])
        lines.append(f"| {c} | {sel.sum()} | {auto[sel].mean():.3f} | {blend[sel].mean():.3f} | "
                     f"{mae[sel, 0].mean():.3f} |")
    write_report(a.out, "blend_apply.md", lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
