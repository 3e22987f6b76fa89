"""Calibrate the shipped confidence on kinds the model was not trained on.

The confidence ``CutoutHeight`` reports is a table: the learned map's win rate
against the contact line in each of five bins of the confidence rule's signal
(``learned_height.calibrated_confidence``). This keeps the rule's signal,
threshold and bin edges (so auto's choice is unchanged on every cutout) and
refits only the win rates, on the folders given with ``--fit``; then it judges
the shipped rates and the refitted ones on named sets of folders (``--judge``):

* ``mean_conf`` vs ``win``: the mean confidence and the share of cutouts on which
  the learned map's MAE [px] is below the contact line's (both as the node gives
  them: pinned, foot-snapped, under the same contact constraint);
* ``binned_error``: sum over the rule's bins of n_b |mean confidence_b - win share_b| / N.

A bin holding fewer than ``--min-bin`` fitting cutouts takes the pooled win share.
The per-cutout rows (signal, bin, both MAEs) are cached in ``--out`` per folder, so
a second run reads them instead of predicting again. ``--write`` stores the refitted
``win_rate`` and what it was fitted on (``win_rate_chosen_on``) in the checkpoint and
writes its numpy weights again (``export --npz``'s ``write_numpy_weights``). The rule it was
run under: docs/height-record.md, "Rules fixed before measuring: the confidence on
unseen kinds".

    python -m pixgraph_lab.height.recalibrate --fit data/hreal/u4_heldout data/hreal/u4_heldout2 \\
        data/hreal/u4_heldout3 --judge U5=data/hreal/u5_heldout,data/hreal/u5_heldout2,data/hreal/u5_heldout3 \\
        --out runs/recal12
"""
from __future__ import annotations

import argparse
import csv
import os
import pathlib

import numpy as np

from .confidence_study import bin_of, fit_win_rates


def calibration(conf: np.ndarray, win: np.ndarray, bins: np.ndarray, n_bins: int) -> dict:
    """``mean_conf``, ``win`` (share), ``gap`` (mean_conf - win) and ``binned_error``
    (sum over bins of n_b |mean conf_b - win_b| / N) of one set."""
    conf = np.asarray(conf, float)
    win = np.asarray(win, bool)
    err = sum(np.sum(bins == b) * abs(conf[bins == b].mean() - win[bins == b].mean())
              for b in range(n_bins) if np.any(bins == b)) / len(conf)
    return {"n": len(conf), "mean_conf": float(conf.mean()), "win": float(win.mean()),
            "gap": float(conf.mean() - win.mean()), "binned_error": float(err)}


def folder_rows(folder: str, pred, out: str) -> list[dict]:
    """Per-cutout rows of one folder of height samples, cached in ``out`` under the
    folder's name, a digest of its full path and the first 12 hex digits of the
    weights' sha256 (other weights, or another folder of the same name, are
    predicted again)."""
    import hashlib

    from pixgraph_nodes.ops.height_net import pt_digest

    from .evaluate import height_files, read_height_sample
    where = hashlib.sha256(os.path.abspath(folder).encode()).hexdigest()[:8]
    cache = os.path.join(out, f"{os.path.basename(os.path.normpath(folder))}-{where}-"
                              f"{pt_digest(pred.path)[:12]}.csv")
    if os.path.exists(cache):
        with open(cache) as fh:
            return [{k: float(v) if k != "object" else v for k, v in r.items()} for r in csv.DictReader(fh)]
    rows = []
    for f in height_files(folder):
        meta, rgba, true, mask = read_height_sample(f)
        r = pred.predict_full(rgba)
        rows.append({"index": float(meta["index"]), "object": meta["object"], "signal": r["signal"],
                     "mae_learned": float(np.abs(r["height"][mask] - true[mask]).mean()),
                     "mae_heuristic": float(np.abs(r["heuristic"][mask] - true[mask]).mean()),
                     "use_learned": float(r["use_learned"])})
    os.makedirs(out, exist_ok=True)
    with open(cache + ".tmp", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    os.replace(cache + ".tmp", cache)
    return rows


def arrays(rows, edges):
    s = np.array([r["signal"] for r in rows])
    win = np.array([r["mae_learned"] < r["mae_heuristic"] for r in rows])
    return bin_of(s, edges), win, np.array([r["use_learned"] > 0.5 for r in rows])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.recalibrate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", default=None, help="checkpoint (default: the shipped one)")
    ap.add_argument("--fit", nargs="+", required=True, help="folders of height samples to fit the win rates on")
    ap.add_argument("--judge", nargs="*", default=[], help="NAME=FOLDER[,FOLDER...] sets to judge both on")
    ap.add_argument("--min-bin", type=int, default=20)
    ap.add_argument("--out", required=True)
    ap.add_argument("--write", action="store_true", help="store the refitted win_rate in the checkpoint")
    a = ap.parse_args(argv)
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor

    from .evaluate import write_inference, write_report
    weights = a.weights or str(WEIGHTS)
    pred = LearnedHeightPredictor(weights)
    rule = pred.confidence_rule
    edges, shipped = rule["bins"], list(rule["win_rate"])
    nb = len(shipped)
    fit_rows = [r for f in a.fit for r in folder_rows(f, pred, a.out)]
    fb, fwin, fuse = arrays(fit_rows, edges)
    refit = fit_win_rates(fb, fwin, nb, a.min_bin)
    lines = [f"weights {weights}; rule signal {rule['signal']}, bin edges {np.round(edges, 3).tolist()}", "",
             f"fitted on {len(fit_rows)} cutouts ({', '.join(a.fit)}), min {a.min_bin} a bin", "",
             "| bin | n (fit) | shipped win_rate | refitted |", "|---|---|---|---|"]
    for b in range(nb):
        lines.append(f"| {b} | {int(np.sum(fb == b))} | {shipped[b]:.3f} | {refit[b]:.3f} |")
    sets = [("fit", fit_rows)] + [(j.split("=", 1)[0], [r for f in j.split("=", 1)[1].split(",")
                                                        for r in folder_rows(f, pred, a.out)]) for j in a.judge]
    lines += ["", "| set | n | win (learned < contact line) | mean confidence: shipped / refitted | "
              "binned error: shipped / refitted | auto keeps the learned map |", "|---|---|---|---|---|---|"]
    per_bin = ["", "| set | bin | n | win | shipped | refitted |", "|---|---|---|---|---|---|"]
    for name, rows in sets:
        b, win, use = arrays(rows, edges)
        cs = calibration(np.take(shipped, b), win, b, nb)
        cr = calibration(np.take(refit, b), win, b, nb)
        lines.append(f"| {name} | {cs['n']} | {cs['win']:.3f} | {cs['mean_conf']:.3f} / {cr['mean_conf']:.3f} | "
                     f"{cs['binned_error']:.3f} / {cr['binned_error']:.3f} | {np.mean(use):.1%} |")
        for k in range(nb):
            if np.any(b == k):
                per_bin.append(f"| {name} | {k} | {int(np.sum(b == k))} | {np.mean(win[b == k]):.3f} | "
                               f"{shipped[k]:.2f} | {refit[k]:.3f} |")
    low = [k for k in range(nb) if refit[k] < 0.5 and np.any(fuse[fb == k])]
    lines += per_bin + ["", "refitted bins below 0.5 where auto keeps the learned map: "
                        + (", ".join(map(str, low)) or "none")]
    write_report(a.out, "recalibrate.md", lines)
    if a.write:
        # chosen_on stays what the signal, threshold and bins were chosen on
        write_inference(weights, confidence=dict(
            rule, win_rate=refit, win_rate_chosen_on=f"{', '.join(a.fit)} ({len(fit_rows)} samples, "
                                                     "python -m pixgraph_lab.height.recalibrate)"))
        print(f"wrote the refitted win_rate into {weights}")
        from .export import write_numpy_weights
        write_numpy_weights(pathlib.Path(weights))      # the numpy weights carry the config too
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
