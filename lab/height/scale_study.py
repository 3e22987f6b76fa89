"""Large cutouts: the learned height at the work size vs at the cutout's own size
(docs/height-record.md, "Rules fixed before measuring: large cutouts" and the rules after it).

    python -m pixgraph_lab.height.scale_study --weights nodes/weights/cutout_height.pt \\
        --heights data/hreal/val data/hreal/val_organic --scales 4 8 --out runs/scale_study

Each sample (256^2) is enlarged k times: the linear premultiplied RGBA and the
true pixel height (x k) bilinearly, the object's mask by nearest neighbour.
Paths (``--paths``, ``contact="ground"``; ``PATHS``): ``work512`` (shipped in the
fifth session: a crop larger than 512 px predicted at that size,
``pixgraph_nodes.ops.height_work_size``, the confidence signals' lengths in
pixels of a crop of at most ``SIGNAL_SIDE``), ``work`` (the same at 256 px with
the signals in the cutout's own pixels, a candidate that did not ship),
``own`` (the path shipped until then: everything at the enlarged size) and
``own_scaled`` (the same with the signals in 256-px units, did not ship).
Reported per scale and path:
the mean MAE over the object's pixels divided by k (256^2 px units, comparable
with k = 1) of the learned map, auto's map and the contact line; the share of
samples auto sends to the contact line; the mean reported confidence, the
learned map's actual share of samples better than the contact line and the gap
between the two; the median time.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from pixgraph_nodes.ops.learned_height import SIGNAL_SIDE


def enlarge(rgba, true, mask, k: int):
    """The sample k times larger (module doc)."""
    import torch
    import torch.nn.functional as F
    t = torch.from_numpy(np.concatenate([rgba, true[..., None]], -1)).permute(2, 0, 1)[None]
    big = F.interpolate(t, scale_factor=k, mode="bilinear", align_corners=False)[0].permute(1, 2, 0).numpy()
    return (np.ascontiguousarray(big[..., :4]), big[..., 4] * k,
            np.repeat(np.repeat(mask, k, 0), k, 1))


def _path(work_side, signal_side):
    """A path of the predictor with these settings (``LearnedHeightPredictor.work_side``
    / ``signal_side``; None: off), restored afterwards."""
    def run(pred, rgba):
        keep = pred.work_side, pred.signal_side
        pred.work_side, pred.signal_side = work_side, signal_side
        try:
            return pred.predict_full(rgba)
        finally:
            pred.work_side, pred.signal_side = keep
    return run


PATHS = {
    # the first candidate: work size 256, signals in the cutout's own pixels (at 256 px the same as 256-px units)
    "work": _path(256, None),
    # the fourth session's last candidate, shipped in the fifth: work size 512, signals in 256-px units
    "work512": _path(512, SIGNAL_SIDE),
    # the path shipped until the fifth session: everything at the cutout's own size
    "own": _path(None, None),
    # the same with the signals in 256-px units (the second candidate)
    "own_scaled": _path(None, SIGNAL_SIDE),
}


def interval(diff, n_boot: int = 10000, seed: int = 0, level: float = 0.95) -> tuple[float, float]:
    """The two-sided ``level`` percentile bootstrap interval (lower, upper) of
    mean(``diff``) (samples resampled with replacement, ``n_boot`` times)."""
    d = np.asarray(diff, np.float64)
    rng = np.random.default_rng(seed)
    means = d[rng.integers(0, len(d), size=(n_boot, len(d)))].mean(1)
    lo, hi = np.quantile(means, [0.5 - level / 2, 0.5 + level / 2])
    return float(lo), float(hi)


def upper_bound(diff, n_boot: int = 10000, seed: int = 0, level: float = 0.95) -> float:
    """The upper end of ``interval``."""
    return interval(diff, n_boot, seed, level)[1]


def noninferiority(rows, new: str, old: str, scales, margin: float, time_ratio: float = 0.75):
    """Report lines and verdict of the non-inferiority rule (docs/height-record.md, "Rules
    fixed before measuring: large cutouts, non-inferiority on fresh samples"): at
    every scale (a) the upper 95 % bootstrap bound of the paired mean difference of
    the learned MAE (new - old) at most ``margin`` x old's mean MAE, (b) the same
    for auto's MAE, (c) the confidence gap no larger; (d) at 8x (when measured) the
    median time at most ``time_ratio`` x old's."""
    lines = [f"Non-inferiority of {new} against {old} (margin {margin:.1%} of {old}'s MAE; 95 % paired bootstrap, "
             "10,000 resamples):", "",
             "| scale | metric | mean new - old [px] | upper 95 % bound [px] | margin [px] | met |",
             "|---|---|---|---|---|---|"]
    ok = []
    for k in scales:
        rs = [r for r in rows if r["k"] == k]
        for metric in ("mae", "mae_auto"):
            d = [r[f"{metric}_{new}"] - r[f"{metric}_{old}"] for r in rs]
            ub, m = upper_bound(d), margin * float(np.mean([r[f"{metric}_{old}"] for r in rs]))
            ok.append(ub <= m)
            lines.append(f"| {k}x | {'learned' if metric == 'mae' else 'auto'} MAE | {np.mean(d):+.3f} | "
                         f"{ub:+.3f} | {m:.3f} | {'yes' if ub <= m else 'no'} |")
        gaps = []
        for p in (new, old):
            win = float(np.mean([r[f"mae_{p}"] < r[f"mae_heuristic_{p}"] for r in rs]))
            gaps.append(abs(float(np.mean([r[f"confidence_{p}"] for r in rs])) - win))
        ok.append(gaps[0] <= gaps[1])
        lines.append(f"| {k}x | confidence gap | {gaps[0] - gaps[1]:+.3f} | | | {'yes' if gaps[0] <= gaps[1] else 'no'} |")
    kt = 8 if 8 in scales else max(scales)
    rs = [r for r in rows if r["k"] == kt]
    tn, to = (float(np.median([r[f"ms_{p}"] for r in rs])) for p in (new, old))
    lines += ["", f"median time at {kt}x: {tn:.0f} vs {to:.0f} ms ({tn / to:.2f}x)"]
    if 8 in scales:
        ok.append(tn <= time_ratio * to)
        lines[-1] += f"; at 8x at most {time_ratio}x: {'yes' if tn <= time_ratio * to else 'no'}"
    else:
        lines[-1] += " (the rule's time is judged at 8x only: not judged here)"
    lines += ["", f"**rule {'met' if all(ok) else 'not met'}**"]
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.scale_study", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", default=None)
    ap.add_argument("--heights", required=True, nargs="+")
    ap.add_argument("--scales", type=int, nargs="+", default=[4, 8])
    ap.add_argument("--paths", default="work,own", help=f"two or more of {', '.join(PATHS)}; the first is "
                                                        "compared with the second by the ship rule")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--margin", type=float, default=None,
                    help="also judge the first path by the non-inferiority rule (noninferiority) with this "
                         "margin, a fraction of the second path's MAE (e.g. 0.02)")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    import torch
    torch.set_num_threads(1)
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor

    from .evaluate import _write, height_files, read_height_sample, write_report
    paths = a.paths.split(",")
    pred = LearnedHeightPredictor(a.weights or WEIGHTS)
    rows = []
    for d in a.heights:
        for f in height_files(d, a.limit):
            meta, rgba, true, mask = read_height_sample(f)
            for k in a.scales:
                big, tb, mb = enlarge(rgba, true, mask, k)
                row = {"folder": d, "index": meta["index"], "category": meta.get("category", "?"), "k": k}
                for path in paths:
                    t0 = time.perf_counter()
                    r = PATHS[path](pred, big)
                    row[f"ms_{path}"] = 1e3 * (time.perf_counter() - t0)
                    for name, h in (("mae", r["height"]), ("mae_auto", r["auto_height"]),
                                    ("mae_heuristic", r["heuristic"])):
                        row[f"{name}_{path}"] = float(np.abs(h[mb] - tb[mb]).mean()) / k
                    row[f"fallback_{path}"] = int(not r.get("use_learned", True))
                    row[f"confidence_{path}"] = float(r["confidence"])
                rows.append(row)
    os.makedirs(a.out, exist_ok=True)
    _write(os.path.join(a.out, "scale.csv"), rows)
    lines = [f"weights {a.weights or WEIGHTS}; {len(rows) // len(a.scales)} samples of {', '.join(a.heights)}; "
             f"MAE in 256-px units", "",
             "| scale | path | MAE learned | MAE auto | MAE contact line | auto falls back | mean confidence | "
             "learned < contact line | confidence gap | median ms |", "|---|---|---|---|---|---|---|---|---|---|"]
    verdict = []
    for k in a.scales:
        rs = [r for r in rows if r["k"] == k]
        res = {}
        for path in paths:
            mean = lambda c: float(np.mean([r[f"{c}_{path}"] for r in rs]))  # noqa: E731
            win = float(np.mean([r[f"mae_{path}"] < r[f"mae_heuristic_{path}"] for r in rs]))
            gap = abs(mean("confidence") - win)
            res[path] = (mean("mae"), mean("mae_auto"), gap)
            lines.append(f"| {k}x | {path} | {mean('mae'):.3f} | {mean('mae_auto'):.3f} | {mean('mae_heuristic'):.3f} | "
                         f"{mean('fallback'):.0%} | {mean('confidence'):.3f} | {win:.0%} | {gap:.3f} | "
                         f"{np.median([r[f'ms_{path}'] for r in rs]):.0f} |")
        new, old = res[paths[0]], res[paths[1]]
        verdict.append((k, new[0] <= old[0], new[1] <= old[1], new[2] <= old[2]))
    lines += ["", f"{paths[0]} vs {paths[1]}, per scale: (learned MAE no worse, auto MAE no worse, confidence gap "
              f"no larger): " + "; ".join(f"{k}x {a_} {b_} {c_}" for k, a_, b_, c_ in verdict)]
    if a.margin is not None:
        lines += ["", *noninferiority(rows, paths[0], paths[1], a.scales, a.margin)]
    write_report(a.out, "scale_study.md", lines)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
