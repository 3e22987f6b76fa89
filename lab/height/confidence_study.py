"""Choose auto's confidence signal and threshold on the validation split
(docs/height-record.md, "Confidence rule").

    python -m pixgraph_lab.height.confidence_study --weights runs/height5/best.pt \\
        --heights data/hreal/val --out runs/confidence_study [--write]

Per sample: the learned map (``LearnedHeightPredictor.predict_full``,
``contact="ground"``, the checkpoint's pin and foot snap), the contact line under
the same constraint, every candidate signal (``learned_height.confidence_signals``)
and the target ``MAE(learned) - MAE(contact line)`` [px]. Each signal is oriented
(multiplied by the sign of its Spearman correlation with the target, so larger
means "the learned map is likely worse"); ``combined`` is a least-squares fit of
the target on the standardised signals, scored out-of-fold (5 folds; the stored
fit uses all samples). The chosen signal has the highest Spearman correlation.
The threshold: among the samples' own values of the chosen signal (and "never"),
the one whose auto map (the contact line where the signal is above it) has the
lowest mean MAE. The calibration: quintile edges of the signal and the learned
map's win rate in each. ``--write`` stores ``config["inference"]["confidence"]``.
"""
from __future__ import annotations

import os

import numpy as np
from scipy.stats import rankdata


def spearman(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 3 or np.ptp(a[ok]) == 0:
        return 0.0
    return float(np.corrcoef(rankdata(a[ok]), rankdata(b[ok]))[0, 1])  # ties share their mean rank


def fit_linear(F, y):
    mu, sd = F.mean(0), F.std(0) + 1e-12
    Z = np.c_[np.ones(len(F)), (F - mu) / sd]
    coef, *_ = np.linalg.lstsq(Z, y, rcond=None)
    return mu, sd, coef


def out_of_fold(F, y, folds=5, seed=0):
    idx = np.random.default_rng(seed).permutation(len(y))
    pred = np.empty(len(y))
    for k in range(folds):
        te = idx[k::folds]
        tr = np.setdiff1d(idx, te)
        mu, sd, coef = fit_linear(F[tr], y[tr])
        pred[te] = coef[0] + ((F[te] - mu) / sd) @ coef[1:]
    return pred


def best_threshold(s, mae_l, mae_h):
    """(threshold, mean auto MAE): the contact line where s > threshold."""
    best = (float("inf"), float(np.mean(mae_l)))
    for t in np.unique(s):
        m = float(np.mean(np.where(s > t, mae_h, mae_l)))
        if m < best[1] - 1e-12:
            best = (float(t), m)
    return best


def bin_of(signal: np.ndarray, edges) -> np.ndarray:
    """The rule's bin index (0 .. len(edges)) of each signal value (``calibrated_confidence``'s)."""
    return np.searchsorted(np.asarray(edges, float), np.asarray(signal, float), side="right")


def fit_win_rates(bins: np.ndarray, win: np.ndarray, n_bins: int, min_bin: int = 20) -> list[float]:
    """The share of ``win`` (bool per cutout) in each bin; a bin with fewer than
    ``min_bin`` cutouts gets the pooled share."""
    pooled = float(np.mean(win))
    return [float(np.mean(win[bins == b])) if np.sum(bins == b) >= min_bin else pooled
            for b in range(n_bins)]


def main(argv=None) -> int:
    from pixgraph_nodes.ops.learned_height import SIGNALS, LearnedHeightPredictor

    from .evaluate import _write, height_files, read_height_sample, study_args, write_inference, write_report
    a = study_args("python -m pixgraph_lab.height.confidence_study", __doc__, argv)
    pred = LearnedHeightPredictor(a.weights)
    pred.confidence_rule = None
    rows = []
    files = height_files(a.heights, a.limit)
    for f in files:
        meta, rgba, true, mask = read_height_sample(f)
        r = pred.predict_full(rgba, signals=True)
        ml = float(np.abs(r["height"][mask] - true[mask]).mean())
        mh = float(np.abs(r["heuristic"][mask] - true[mask]).mean())
        rows.append({"index": meta["index"], "category": meta.get("category", "?"), "mae_learned": ml,
                     "mae_heuristic": mh, "target": ml - mh} | r["signals"])
    os.makedirs(a.out, exist_ok=True)
    _write(os.path.join(a.out, "signals.csv"), rows)
    y = np.array([r["target"] for r in rows])
    feats = [k for k in SIGNALS if np.all(np.isfinite([r[k] for r in rows]))]
    F = np.array([[r[k] for k in feats] for r in rows])
    rho, oriented = {}, {}
    for j, k in enumerate(feats):
        c = spearman(F[:, j], y)
        sign = 1.0 if c >= 0 else -1.0
        rho[k], oriented[k] = abs(c), (sign, sign * F[:, j])
    oof = out_of_fold(F, y)
    rho["combined"] = spearman(oof, y)
    best = max(rho, key=lambda k: rho[k])
    mu, sd, coef = fit_linear(F, y)
    if best == "combined":
        s = coef[0] + ((F - mu) / sd) @ coef[1:]
        rule = {"signal": "combined", "features": feats, "mean": mu.tolist(), "std": sd.tolist(),
                "bias": float(coef[0]), "weights": coef[1:].tolist()}
    else:
        sign, s = oriented[best]
        rule = {"signal": best, "sign": sign}
    mae_l = np.array([r["mae_learned"] for r in rows])
    mae_h = np.array([r["mae_heuristic"] for r in rows])
    thr, auto_mae = best_threshold(s, mae_l, mae_h)
    edges = np.quantile(s, [0.2, 0.4, 0.6, 0.8])
    win = fit_win_rates(bin_of(s, edges), mae_l < mae_h, 5, min_bin=1)     # quintiles: none empty
    rule.update(threshold=thr if np.isfinite(thr) else 1e30, bins=edges.tolist(), win_rate=win,
                spearman=rho[best], chosen_on=f"{a.heights} ({len(rows)} samples)")
    use = s <= rule["threshold"]
    lines = [f"weights {a.weights}, {len(rows)} samples of {a.heights}", "",
             "Spearman correlation with MAE(learned) - MAE(contact line), oriented (sign):", "",
             "| signal | Spearman | sign |", "|---|---|---|"]
    for kk in list(feats) + ["combined"]:
        lines.append(f"| {kk} | {rho[kk]:.3f} | {'' if kk == 'combined' else int(oriented[kk][0])} |")
    lines += ["", f"chosen: {best} (Spearman {rho[best]:.3f}); threshold {rule['threshold']:.4g}; "
              f"the contact line on {np.mean(~use):.0%} of the samples",
              f"calibration: quintile edges {np.round(edges, 4).tolist()}, learned win rate per bin "
              f"{[round(w, 2) for w in win]}", "",
              "| category | n | MAE learned | MAE auto | MAE contact line | auto falls back | learned < contact line |",
              "|---|---|---|---|---|---|---|"]
    cats = ["all"] + sorted({r["category"] for r in rows})
    auto = np.where(use, mae_l, mae_h)
    for c in cats:
        sel = np.array([c == "all" or r["category"] == c for r in rows])
        lines.append(f"| {c} | {sel.sum()} | {mae_l[sel].mean():.2f} | {auto[sel].mean():.2f} | "
                     f"{mae_h[sel].mean():.2f} | {np.mean(~use[sel]):.0%} | {np.mean((mae_l < mae_h)[sel]):.0%} |")
    write_report(a.out, "confidence_study.md", lines)
    if a.write:
        write_inference(a.weights, confidence=rule)
        print(f"wrote the confidence rule ({best}) into {a.weights}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
