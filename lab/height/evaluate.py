"""Evaluate the learned cutout pixel-height predictor against the contact-line heuristic.

    python -m pixgraph_lab.height.evaluate --heights data/height/test --shadows data/wall_test64 \
        --out runs/height_eval

1. Pixel height (``--heights``, a ``pixgraph_lab.height.generate`` test split:
   objects never seen in training): per sample the mean |predicted - true| pixel
   height over the object's pixels (the centre-ray mask), in px and relative to
   the object's largest true pixel height; averaged over samples, by pose
   (upright / tilted / lying / random) and for overhangs.
2. Downstream (``--shadows``, a ground-truth benchmark from
   ``pixgraph_lab.datagen.generate``, e.g. ``--benchmark wall --split test``): the
   classical pixel-height soft shadow (``soft:N`` of ``pixgraph_lab.evaluate``)
   traced with the cutout height (a) true (the renderer's ``fg_height``), (b)
   predicted, (c) the contact-line heuristic, scored against the renderer's
   ground-truth darkness with ``lab/metrics.py`` (RMSE over visible background
   pixels outside the cutout), overall and by object group.

Writes ``OUT/heights.csv``, ``OUT/shadows.csv`` and ``OUT/report.md``.
"""
from __future__ import annotations

import argparse
import csv
import glob
import json
import os
import time

import numpy as np


def srgb_decode(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _rgba_from_height_sample(z):
    a = z["alpha"].astype(np.float32) / 255
    rgb = srgb_decode(z["rgb"].astype(np.float32) / 255)
    return np.concatenate([rgb * a[..., None], a[..., None]], 2).astype(np.float32)


def height_files(data_dir, limit=0):
    """The split's sample files in order, the first ``limit`` (0: all)."""
    return sorted(glob.glob(os.path.join(data_dir, "[0-9]" * 5 + ".npz")))[: limit or None]


def read_height_sample(f):
    """(meta, premultiplied linear RGBA, true height float32, mask) of one sample file."""
    with np.load(f, allow_pickle=False) as z:
        return (json.loads(str(z["meta"])), _rgba_from_height_sample(z), z["height"].astype(np.float32),
                z["mask"])


def study_args(prog, doc, argv=None):
    """The arguments every validation study takes (--weights, --heights, --limit, --out,
    --write), parsed; torch set to one thread."""
    ap = argparse.ArgumentParser(prog=prog, description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", required=True)
    ap.add_argument("--heights", required=True)
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--out", required=True)
    ap.add_argument("--write", action="store_true")
    a = ap.parse_args(argv)
    import torch
    torch.set_num_threads(1)
    return a


def write_report(out, name, lines):
    """Write ``lines`` (one string each) as ``out/name`` (creating ``out``) and print them."""
    text = "\n".join(lines) + "\n"
    os.makedirs(out, exist_ok=True)
    with open(os.path.join(out, name), "w") as fh:
        fh.write(text)
    print(text)


def write_inference(weights, **entries):
    """Set ``entries`` in the checkpoint's ``config["inference"]`` in place (written atomically)."""
    import torch
    ck = torch.load(weights, map_location="cpu", weights_only=True)
    cfg = json.loads(ck["config"]) if isinstance(ck["config"], str) else dict(ck["config"])
    cfg.setdefault("inference", {}).update(entries)
    ck["config"] = json.dumps(cfg)
    torch.save(ck, weights + ".tmp")
    os.replace(weights + ".tmp", weights)


def height_errors(pred, true, mask):
    m = mask.astype(bool)
    if not m.any():
        return float("nan"), float("nan")
    mae = float(np.abs(pred[m] - true[m]).mean())
    return mae, mae / max(float(true[m].max()), 1e-6)


def eval_heights(data_dir, predictor, limit=0):
    from pixgraph_nodes.ops.heightmaps import contact_line_height
    rows = []
    for f in height_files(data_dir, limit):
        meta, rgba, true, mask = read_height_sample(f)
        t0 = time.perf_counter()
        pl = predictor.predict(rgba)
        ms = 1e3 * (time.perf_counter() - t0)
        ph = contact_line_height(rgba[..., 3])
        mae_l, rel_l = height_errors(pl, true, mask)
        mae_h, rel_h = height_errors(ph, true, mask)
        rows.append({"index": meta["index"], "object": meta["object"], "pose": meta["pose"],
                     "overhang": int(meta["overhang"]), "object_px": float(true[mask].max()),
                     "learned_mae_px": mae_l, "learned_rel": rel_l,
                     "heuristic_mae_px": mae_h, "heuristic_rel": rel_h, "ms": ms})
    return rows


def shadow_sample(f, device):
    """One shadow-benchmark sample as the height evaluations use it: the prepared
    sample, the receiver pixels scored (background, valid), the ground-truth darkness
    (float64), the cutout as premultiplied float32 RGBA, and its mask."""
    from pixgraph_lab.evaluate import prepared_sample

    s = prepared_sample(f, device)
    a = s["alpha"].astype(np.float32)
    rgba = np.concatenate([s["rgb"].astype(np.float32) * a[..., None], a[..., None]], 2)
    return s, ~s["mask"] & s["bg_valid"], s["shadow"].astype(np.float64), rgba, s["mask"]


def eval_shadows(data_dir, predictor, n_samples=64, limit=0, thickness=1.0):
    from pixgraph.device import Device
    from pixgraph_nodes.ops.heightmaps import contact_line_height

    from pixgraph_lab.datagen.dataset import sample_files
    from pixgraph_lab.evaluate import Method
    from pixgraph_lab.metrics import shadow_metrics

    from .generate import is_overhang
    device = Device.open()
    soft = Method(f"soft:{n_samples}", thickness)
    rows = []
    for f in sample_files(data_dir)[: limit or None]:
        s, valid, g, rgba, mask = shadow_sample(f, device)
        heights = {"true": s["fg_height"].astype(np.float32),
                   "learned": predictor.predict(rgba),
                   "heuristic": contact_line_height(mask.astype(np.float32))}
        obj = s["meta"]["scene"]["object"]
        row = {"index": s["meta"]["index"], "object": obj, "background": s["meta"]["scene"]["background"],
               "group": "figure (upright)" if obj == "proc:figure" else "urdf (random rotation)",
               "overhang": int(is_overhang(mask, heights["true"]))}
        for k, h in heights.items():
            s2 = dict(s, fg_height=np.where(mask, h, 0.0).astype(np.float32))
            p = soft.predict(s2)
            row[f"rmse_{k}"] = shadow_metrics(np.clip(p, 0, 1), g, valid)["rmse"]
            if k != "true":
                row[f"mae_{k}"] = height_errors(h, heights["true"], mask)[0]
        rows.append(row)
    return rows


def _write(path, rows):
    if not rows:
        return
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def height_table(rows) -> str:
    groups = [("all", lambda r: True)] + [(p, (lambda p: lambda r: r["pose"] == p)(p))
                                          for p in ("upright", "tilted", "lying", "random")]
    groups += [("overhang", lambda r: r["overhang"]), ("not overhang", lambda r: not r["overhang"]),
               ("not upright", lambda r: r["pose"] != "upright")]
    lines = ["| objects | n | learned MAE px | heuristic MAE px | learned MAE / height | heuristic MAE / height |",
             "|---|---|---|---|---|---|"]
    for name, sel in groups:
        rs = [r for r in rows if sel(r)]
        if not rs:
            continue
        m = lambda k: float(np.mean([r[k] for r in rs]))  # noqa: E731
        lines.append(f"| {name} | {len(rs)} | {m('learned_mae_px'):.2f} | {m('heuristic_mae_px'):.2f} | "
                     f"{m('learned_rel'):.3f} | {m('heuristic_rel'):.3f} |")
    return "\n".join(lines) + "\n"


def shadow_table(rows) -> str:
    groups = [("all", lambda r: True), ("figure (upright)", lambda r: r["group"] == "figure (upright)"),
              ("urdf (random rotation)", lambda r: r["group"] != "figure (upright)"),
              ("overhang", lambda r: r["overhang"]), ("not overhang", lambda r: not r["overhang"])]
    lines = ["| objects | n | RMSE true h | RMSE learned h | RMSE heuristic h | learned / true | "
             "learned vs heuristic | height MAE learned / heuristic px |",
             "|---|---|---|---|---|---|---|---|"]
    for name, sel in groups:
        rs = [r for r in rows if sel(r)]
        if not rs:
            continue
        m = lambda k: float(np.mean([r[k] for r in rs]))  # noqa: E731
        t, lrn, h = m("rmse_true"), m("rmse_learned"), m("rmse_heuristic")
        lines.append(f"| {name} | {len(rs)} | {t:.4f} | {lrn:.4f} | {h:.4f} | {lrn / t - 1:+.1%} | "
                     f"{lrn / h - 1:+.1%} | {m('mae_learned'):.1f} / {m('mae_heuristic'):.1f} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.evaluate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--heights", help="height test split (pixgraph_lab.height.generate --split test)")
    ap.add_argument("--shadows", help="ground-truth benchmark folder (pixgraph_lab.datagen.generate)")
    ap.add_argument("--weights", default=None, help="checkpoint (default: the shipped weights)")
    ap.add_argument("--samples", type=int, default=64, help="light samples of the soft shadow")
    ap.add_argument("--thickness", type=float, default=1.0,
                    help="occluder thickness [px] of the soft shadow (1: the first report; "
                         "6: the example graphs' default)")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    import torch
    torch.set_num_threads(a.threads)
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor
    predictor = LearnedHeightPredictor(a.weights or WEIGHTS)
    os.makedirs(a.out, exist_ok=True)
    report = [f"weights: {a.weights or WEIGHTS}\n"]
    if a.heights:
        rows = eval_heights(a.heights, predictor, a.limit)
        _write(os.path.join(a.out, "heights.csv"), rows)
        report += [f"## Pixel height on {a.heights} ({len(rows)} samples, objects unseen in training)\n",
                   height_table(rows)]
    if a.shadows:
        rows = eval_shadows(a.shadows, predictor, a.samples, a.limit, a.thickness)
        _write(os.path.join(a.out, "shadows.csv"), rows)
        report += [f"\n## Soft shadow (soft:{a.samples}, thickness {a.thickness:g} px) on {a.shadows} "
                   f"({len(rows)} samples)\n",
                   shadow_table(rows)]
    text = "\n".join(report)
    with open(os.path.join(a.out, "report.md"), "w") as fh:
        fh.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
