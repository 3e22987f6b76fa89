"""Where methods fail: error against light elevation, light softness and wall distance.

Input: the per-sample rows of ``evaluate.py`` (or its ``per_sample.csv``):

    python -m pixgraph_lab.failure --rows data/wall_test/eval/per_sample.csv --out data/wall_test/eval

For each factor — light elevation seen from the object's centre [deg], relative
light radius r / distance (softness), object-wall clearance [world units, camera
height = 1], and background kind — samples are binned and the mean RMSE of every
method is plotted per bin (``failure_<factor>.png``). The text summary names, per
method and factor, the worst bin and its mean RMSE as a multiple of the method's
mean over all samples (the "breaking point"); bins with fewer than 5 samples are
not named.
"""
from __future__ import annotations

import argparse
import csv
import math

import numpy as np

FACTORS = {
    "elevation_deg": ("light elevation [deg]", np.array([5, 15, 25, 35, 45, 55, 65, 80.0001]), False),
    "relative_radius": ("light radius / distance", np.geomspace(0.015, 0.45001, 7), True),
    "wall_clearance": ("object-wall clearance [world]", np.geomspace(0.02, 1.50001, 6), True),
}
MIN_BIN = 5


def _binned(rows, method, key, edges):
    rs = [r for r in rows if r["method"] == method and np.isfinite(float(r[key]))]
    x = np.array([float(r[key]) for r in rs])
    y = np.array([float(r["rmse"]) for r in rs])
    idx = np.digitize(x, edges) - 1
    means, counts = [], []
    for b in range(len(edges) - 1):
        sel = idx == b
        counts.append(int(sel.sum()))
        means.append(float(y[sel].mean()) if sel.any() else float("nan"))
    return np.array(means), np.array(counts), (float(y.mean()) if len(y) else float("nan"))


def failure_charts(rows, out_dir: str) -> list[str]:
    """Write failure_<factor>.png into out_dir; return the breaking-point lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    methods = list(dict.fromkeys(r["method"] for r in rows))
    lines = []
    for key, (label, edges, logx) in FACTORS.items():
        if not any(np.isfinite(float(r[key])) for r in rows):
            continue
        fig, ax = plt.subplots(figsize=(6, 4))
        centers = np.sqrt(edges[:-1] * edges[1:]) if logx else (edges[:-1] + edges[1:]) / 2
        for m in methods:
            means, counts, overall = _binned(rows, m, key, edges)
            ok = counts >= 1
            ax.plot(centers[ok], means[ok], "o-", label=m, ms=3)
            big = np.where(counts >= MIN_BIN, means, np.nan)
            if np.isfinite(big).any():
                b = int(np.nanargmax(big))
                lines.append(f"{m:>14s} | {label}: worst bin [{edges[b]:.3g}, {edges[b + 1]:.3g}) "
                             f"RMSE {big[b]:.4f} = {big[b] / overall:.2f}x its mean {overall:.4f} "
                             f"(n={counts[b]})")
        if logx:
            ax.set_xscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("mean RMSE")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(f"{out_dir}/failure_{key}.png", dpi=110)
        plt.close(fig)
    # background kind: grouped bars
    kinds = sorted({r["background"] for r in rows})
    if kinds:
        fig, ax = plt.subplots(figsize=(7, 4))
        w = 0.8 / max(1, len(methods))
        for j, m in enumerate(methods):
            vals = [np.mean([float(r["rmse"]) for r in rows if r["method"] == m and r["background"] == k] or [math.nan])
                    for k in kinds]
            ax.bar(np.arange(len(kinds)) + j * w, vals, w, label=m)
        ax.set_xticks(np.arange(len(kinds)) + 0.4 - w / 2)
        ax.set_xticklabels(kinds)
        ax.set_ylabel("mean RMSE")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(f"{out_dir}/failure_background.png", dpi=110)
        plt.close(fig)
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.failure", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", required=True, help="per_sample.csv written by pixgraph_lab.evaluate")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    with open(a.rows) as fh:
        rows = list(csv.DictReader(fh))
    for line in failure_charts(rows, a.out):
        print(line)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
