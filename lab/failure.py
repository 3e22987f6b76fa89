"""Where methods fail: error against light elevation, light softness, wall distance and object thinness.

Input: the per-sample rows of ``evaluate.py`` (or its ``per_sample.csv``):

    python -m pixgraph_lab.failure --rows data/wall_test/eval/per_sample.csv --out data/wall_test/eval

For each factor — light elevation seen from the object's centre [deg] (bins 5 deg
wide near the horizon), relative light radius r / distance (softness),
object-wall clearance [world units, camera height = 1], the cutout's relative
stroke width (thinness, ``stroke_width``) and background kind — samples are binned and the mean RMSE of every
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
    "elevation_deg": ("light elevation [deg]", np.array([0, 5, 10, 15, 25, 35, 45, 55, 65, 80.0001]), False),
    "relative_radius": ("light radius / distance", np.geomspace(0.015, 0.45001, 7), True),
    "wall_clearance": ("object-wall clearance [world]", np.geomspace(0.02, 1.50001, 6), True),
    "stroke_width": ("cutout stroke width / size (low = thin)",
                     np.array([0.03, 0.1, 0.14, 0.18, 0.22, 0.27, 0.33, 0.70001]), True),
}
MIN_BIN = 5


def stroke_width(mask) -> float:
    """Relative stroke width of a cutout: 4 x the mean distance from a mask pixel to
    the nearest background pixel's edge, over the mask's larger bounding-box side.

    The mean distance to the boundary of a long stroke of width w is w/4, so the
    numerator is the stroke width [px] of bars and frames; for a filled square or
    disc it is 2/3 of the side or diameter, so compact objects score ~0.67 and thin
    ones ~ width / length (a 6 px table top with 6 px legs in a 108 px box: 0.056;
    a 100 px frame 4 px wide: 0.040). Chosen over the area / bounding box or
    area / convex hull ratios because those call a post or a plank solid (ratio 1):
    what makes a shadow hard to get right is narrow structure, open or not.
    Low = thin. The image border counts as background (mask padded by 0).
    """
    from scipy.ndimage import distance_transform_edt
    m = np.pad(np.asarray(mask) > 0.5, 1)
    if not m.any():
        return float("nan")
    width = 4.0 * float((distance_transform_edt(m)[m] - 0.5).mean())
    ys, xs = np.nonzero(m)
    return width / float(max(np.ptp(ys), np.ptp(xs)) + 1)


def _value(r, key) -> float:
    return float(r.get(key, "nan") or "nan")        # older per_sample.csv lack newer factors


def _binned(rows, method, key, edges):
    rs = [r for r in rows if r["method"] == method and np.isfinite(_value(r, key))]
    x = np.array([_value(r, key) for r in rs])
    y = np.array([float(r["rmse"]) for r in rs])
    idx = np.digitize(x, edges) - 1
    means, counts = [], []
    for b in range(len(edges) - 1):
        sel = idx == b
        counts.append(int(sel.sum()))
        means.append(float(y[sel].mean()) if sel.any() else float("nan"))
    return np.array(means), np.array(counts), (float(y.mean()) if len(y) else float("nan"))


def bin_table(rows, key: str, methods=None) -> str:
    """Mean RMSE per bin of ``key`` and method, with the bin's sample count (Markdown)."""
    label, edges, _ = FACTORS[key]
    methods = methods or list(dict.fromkeys(r["method"] for r in rows))
    binned = {m: _binned(rows, m, key, edges) for m in methods}
    counts = binned[methods[0]][1]
    keep = [b for b in range(len(edges) - 1) if counts[b]]
    head = [f"[{edges[b]:.3g}, {edges[b + 1]:.3g}) n={counts[b]}" for b in keep]
    lines = [f"| {label} | " + " | ".join(head) + " | all |", "|---|" + "---|" * (len(keep) + 1)]
    for m in methods:
        means, _, overall = binned[m]
        lines.append(f"| {m} | " + " | ".join(f"{means[b]:.4f}" for b in keep) + f" | {overall:.4f} |")
    return "\n".join(lines) + "\n"


def failure_charts(rows, out_dir: str, prefix: str = "failure_", title: str = "") -> list[str]:
    """Write <prefix><factor>.png into out_dir; return the breaking-point lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    methods = list(dict.fromkeys(r["method"] for r in rows))
    lines = []
    for key, (label, edges, logx) in FACTORS.items():
        if not any(np.isfinite(_value(r, key)) for r in rows):
            continue
        fig, ax = plt.subplots(figsize=(8, 4))
        centers = np.sqrt(edges[:-1] * edges[1:]) if logx else (edges[:-1] + edges[1:]) / 2
        for m in methods:
            means, counts, overall = _binned(rows, m, key, edges)
            ok = counts >= 1
            if m == methods[0]:                     # every method sees the same samples
                for c, n in zip(centers[ok], counts[ok]):
                    ax.annotate(f"n={n}", (c, 0.0), xycoords=("data", "axes fraction"), xytext=(0, 3),
                                textcoords="offset points", ha="center", fontsize=6, color="gray")
            ax.plot(centers[ok], means[ok], "o-", label=m, ms=3)
            big = np.where(counts >= MIN_BIN, means, np.nan)
            if np.isfinite(big).any():
                b = int(np.nanargmax(big))
                lines.append(f"{m:>14s} | {label}: worst bin [{edges[b]:.3g}, {edges[b + 1]:.3g}) "
                             f"RMSE {big[b]:.4f} = {big[b] / overall:.2f}x its mean {overall:.4f} "
                             f"(n={counts[b]})")
        if logx:
            ax.set_xscale("log")
        ax.set_xticks(edges, [f"{e:.2g}" for e in edges], fontsize=7)   # the bin edges
        ax.minorticks_off()
        ax.set_xlabel(label)
        ax.set_ylabel("mean RMSE")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
        if title:
            ax.set_title(title, fontsize=9)
        fig.tight_layout()
        fig.savefig(f"{out_dir}/{prefix}{key}.png", dpi=110)
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
        fig.savefig(f"{out_dir}/{prefix}background.png", dpi=110)
        plt.close(fig)
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.failure", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rows", required=True, help="per_sample.csv written by pixgraph_lab.evaluate")
    ap.add_argument("--out", required=True)
    ap.add_argument("--prefix", default="failure_", help="chart file names: <out>/<prefix><factor>.png")
    ap.add_argument("--method", action="append", default=[], help="only these methods (repeatable; default all)")
    ap.add_argument("--title", default="", help="chart title")
    ap.add_argument("--tables", action="store_true", help="also print RMSE per bin and method, with counts")
    a = ap.parse_args(argv)
    with open(a.rows) as fh:
        rows = list(csv.DictReader(fh))
    if a.method:
        missing = [m for m in a.method if not any(r["method"] == m for r in rows)]
        if missing:
            ap.error(f"{a.rows}: no rows for method {missing[0]!r}")
        rows = [r for r in rows if r["method"] in a.method]
    for line in failure_charts(rows, a.out, a.prefix, a.title):
        print(line)
    if a.tables:
        for key in FACTORS:
            if any(np.isfinite(_value(r, key)) for r in rows):
                print("\n" + bin_table(rows, key))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
