"""Evaluate cutout pixel heights on the real-cutout splits, per category (issue 24's goals).

    python -m pixgraph_lab.height.evaluate_real --heights data/hreal/test \
        --shadows data/hreal/wall_named64 --weights nodes/weights/cutout_height.pt \
        --baseline runs/height_v2.pt --out runs/hreal_eval

1. Pixel height (``--heights``: a ``generate --mix real`` split): per sample and
   per map (``learned``: ``--weights`` through ``LearnedHeightPredictor.predict``
   with ``contact="ground"``; ``learned_free``: the same network without the
   contact pin; ``baseline``: ``--baseline`` pinned the same way; ``heuristic``:
   the contact line; ``auto``: the ``CutoutHeight`` auto rule, ``auto_height`` of
   ``predict_full``) the mean |predicted - true| over the object's pixels
   (the centre-ray mask); the share of samples where ``learned`` beats the
   heuristic; the foot error: how high above the ground the map puts the
   object's visible foot, the mean predicted height over the pixels whose true
   height is < 1 px (inside the alpha > 0.5 mask; samples without such pixels,
   e.g. a ball whose contact is hidden, have none); time of ``predict_full``.
   Grouped by ``category``.
2. Shadows (``--shadows``: a ``shadow_test`` benchmark): ``soft:64`` and SSN++
   (``pixgraph_lab.ssn.methods:node``, the SoftShadowSSN node's computation)
   traced with the true, learned, auto and heuristic heights; RMSE of darkness
   against the renderer's ground truth over the visible background outside the
   cutout (``lab/metrics.py``); the ratio of means learned / true per method and
   object.

Writes ``OUT/heights.csv``, ``OUT/shadows.csv``, ``OUT/report.md`` (and prints it).
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from .evaluate import _write, height_files, read_height_sample


def _errs(pred, true, mask, foot_px):
    m = mask.astype(bool)
    mae = float(np.abs(pred[m] - true[m]).mean())
    foot = float(np.abs(pred[foot_px]).mean()) if foot_px.any() else float("nan")
    return mae, foot


def eval_heights(data_dir, predictor, baseline=None, limit=0, shard=(0, 1)):
    rows = []
    for f in height_files(data_dir, limit)[shard[0]::shard[1]]:
        meta, rgba, true, mask = read_height_sample(f)
        band = mask & (rgba[..., 3] > 0.5) & (true < 1.0)
        t0 = time.perf_counter()
        r = predictor.predict_full(rgba)
        ms = 1e3 * (time.perf_counter() - t0)
        free = predictor.predict(rgba, contact="free")
        conf = r["confidence"]
        maps = {"learned": r["height"], "learned_free": free, "heuristic": r["heuristic"]}
        maps["auto"] = r["auto_height"]
        if baseline is not None:
            maps["baseline"] = baseline.predict(rgba)
        row = {"index": meta["index"], "category": meta.get("category", "?"), "object": meta["object"],
               "pose": meta["pose"], "overhang": int(meta["overhang"]), "object_px": float(true[mask].max()),
               "confidence": float("nan") if conf is None else conf, "ms": ms, "foot_px": int(band.sum()),
               "fallback": int(not r.get("use_learned", True))}
        for k, h in maps.items():
            row[f"mae_{k}"], row[f"foot_{k}"] = _errs(h, true, mask, band)
        rows.append(row)
    return rows


def height_table(rows, keys) -> str:
    cats = ["all"] + sorted({r["category"] for r in rows})
    head = " | ".join(f"MAE {k}" for k in keys)
    lines = [f"| category | n (with a visible foot) | {head} | learned < heuristic | auto falls back "
             f"| foot learned (median) | foot free (median) | foot heuristic (median) |",
             "|---|---|" + "---|" * (len(keys) + 5)]
    for c in cats:
        rs = [r for r in rows if c == "all" or r["category"] == c]
        m = lambda k: float(np.mean([r[k] for r in rs]))  # noqa: E731
        med = lambda k: float(np.nanmedian([r[k] for r in rs]))  # noqa: E731
        win = float(np.mean([r["mae_learned"] < r["mae_heuristic"] for r in rs]))
        nf = sum(r["foot_px"] > 0 for r in rs)
        cells = " | ".join(f"{m('mae_' + k):.2f}" for k in keys)
        fb = float(np.mean([r.get("fallback", 0) for r in rs]))
        lines.append(f"| {c} | {len(rs)} ({nf}) | {cells} | {win:.0%} | {fb:.0%} | {med('foot_learned'):.2f} | "
                     f"{med('foot_learned_free'):.2f} | {med('foot_heuristic'):.2f} |")
    return "\n".join(lines) + "\n"


def eval_shadows(data_dir, predictor, n_samples=64, limit=0, thickness=1.0, ssn=True, shard=(0, 1)):
    from pixgraph.device import Device

    from pixgraph_lab.datagen.dataset import sample_files
    from pixgraph_lab.evaluate import Method
    from pixgraph_lab.metrics import shadow_metrics
    device = Device.open()
    methods = {"soft64": Method(f"soft:{n_samples}", thickness)}
    if ssn:
        methods["ssnpp"] = Method("pixgraph_lab.ssn.methods:node")
    rows = []
    from .evaluate import shadow_sample

    for f in sample_files(data_dir)[: limit or None][shard[0]::shard[1]]:
        s, valid, g, rgba, mask = shadow_sample(f, device)
        r = predictor.predict_full(rgba)
        conf = r["confidence"]
        heights = {"true": s["fg_height"].astype(np.float32), "learned": r["height"], "heuristic": r["heuristic"]}
        heights["auto"] = r["auto_height"]
        row = {"index": s["meta"]["index"], "object": s["meta"]["scene"]["object"],
               "confidence": float("nan") if conf is None else conf}
        for k, h in heights.items():
            s2 = dict(s, fg_height=np.where(mask, h, 0.0).astype(np.float32))
            for mn, meth in methods.items():
                p = meth.predict(s2)
                row[f"{mn}_{k}"] = shadow_metrics(np.clip(p, 0, 1), g, valid)["rmse"]
        rows.append(row)
    return rows


def shadow_table(rows) -> str:
    meths = [m for m in ("soft64", "ssnpp") if f"{m}_true" in rows[0]]
    objs = ["all"] + sorted({r["object"] for r in rows})
    lines = ["| object | n | " + " | ".join(f"{m}: RMSE true, learned, auto, heuristic | {m} learned / true"
                                           for m in meths) + " |",
             "|---|---|" + "---|---|" * len(meths)]
    for o in objs:
        rs = [r for r in rows if o == "all" or r["object"] == o]
        cells = []
        for m in meths:
            v = {k: float(np.mean([r[f"{m}_{k}"] for r in rs])) for k in ("true", "learned", "auto", "heuristic")}
            cells.append(f"{v['true']:.4f}, {v['learned']:.4f}, {v['auto']:.4f}, {v['heuristic']:.4f} | "
                         f"{v['learned'] / v['true']:.2f}x (auto {v['auto'] / v['true']:.2f}x, "
                         f"heuristic {v['heuristic'] / v['true']:.2f}x)")
        lines.append(f"| {o} | {len(rs)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.evaluate_real", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--heights", help="a generate --mix real split folder")
    ap.add_argument("--shadows", help="a shadow_test benchmark folder")
    ap.add_argument("--weights", default=None, help="checkpoint (default: the shipped weights)")
    ap.add_argument("--baseline", default=None, help="a second checkpoint to compare (pinned the same way)")
    ap.add_argument("--samples", type=int, default=64)
    ap.add_argument("--no-ssn", action="store_true")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--shard", default="0/1",
                    help="i/n: evaluate every n-th sample from the i-th (run n shards in parallel, then --merge)")
    ap.add_argument("--merge", nargs="+", default=None,
                    help="output folders of shards: combine their heights.csv / shadows.csv into --out's report")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    if a.merge:
        return merge(a.merge, a.out)
    shard = tuple(int(v) for v in a.shard.split("/"))
    import torch
    torch.set_num_threads(a.threads)
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor
    predictor = LearnedHeightPredictor(a.weights or WEIGHTS)
    baseline = LearnedHeightPredictor(a.baseline) if a.baseline else None
    os.makedirs(a.out, exist_ok=True)
    report = [f"weights: {a.weights or WEIGHTS}" + (f"; baseline: {a.baseline}" if a.baseline else "") + "\n"]
    if a.heights:
        rows = eval_heights(a.heights, predictor, baseline, a.limit, shard)
        _write(os.path.join(a.out, "heights.csv"), rows)
        keys = ["learned", "learned_free", "auto", "heuristic"] + (["baseline"] if baseline else [])
        ms = [r["ms"] for r in rows]
        report += [f"## Pixel height on {a.heights} ({len(rows)} samples)\n", height_table(rows, keys),
                   f"\npredict_full time: median {np.median(ms):.1f} ms over {len(ms)} samples "
                   f"(256^2, one torch thread, shared machine)\n"]
    if a.shadows:
        rows = eval_shadows(a.shadows, predictor, a.samples, a.limit, ssn=not a.no_ssn, shard=shard)
        _write(os.path.join(a.out, "shadows.csv"), rows)
        report += [f"\n## Shadows on {a.shadows} ({len(rows)} samples)\n", shadow_table(rows)]
    text = "\n".join(report)
    with open(os.path.join(a.out, "report.md"), "w") as fh:
        fh.write(text)
    print(text)
    return 0


def _read(path):
    import csv
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        for k, v in r.items():
            if k not in ("category", "object", "pose"):
                try:
                    r[k] = float(v)
                except ValueError:
                    pass
    return rows


def merge(dirs, out) -> int:
    """The report of several ``--shard`` runs (their CSVs concatenated, sorted by index)."""
    os.makedirs(out, exist_ok=True)
    report = [f"merged from {', '.join(dirs)}\n"]
    hs = [r for d in dirs if os.path.exists(os.path.join(d, "heights.csv")) for r in _read(os.path.join(d, "heights.csv"))]
    if hs:
        hs.sort(key=lambda r: r["index"])
        _write(os.path.join(out, "heights.csv"), hs)
        keys = [k[4:] for k in hs[0] if k.startswith("mae_")]
        keys = [k for k in ("learned", "learned_free", "auto", "heuristic", "baseline") if k in keys]
        ms = [r["ms"] for r in hs]
        report += [f"## Pixel height ({len(hs)} samples)\n", height_table(hs, keys),
                   f"\npredict_full time: median {np.median(ms):.1f} ms over {len(ms)} samples "
                   f"(256^2, one torch thread, shared machine)\n"]
    ss = [r for d in dirs if os.path.exists(os.path.join(d, "shadows.csv")) for r in _read(os.path.join(d, "shadows.csv"))]
    if ss:
        ss.sort(key=lambda r: r["index"])
        _write(os.path.join(out, "shadows.csv"), ss)
        report += [f"\n## Shadows ({len(ss)} samples)\n", shadow_table(ss)]
    text = "\n".join(report)
    with open(os.path.join(out, "report.md"), "w") as fh:
        fh.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
