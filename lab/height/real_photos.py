"""The "real-photo" check of docs/height.md: cutouts rendered by the project with known heights,
side by side: heuristic, learned and hand-edited heights and their shadows.

    python -m pixgraph_lab.height.real_photos --shadows data/hreal/wall_named64 \
        --out docs/img/height_real.png --table runs/real_photos.md

Samples (rule fixed before looking at any prediction): from the named-mesh
ground-truth benchmark (``shadow_test``: our Mitsuba renders of pybullet_data's
named meshes, never trained on, with exact pixel heights and ground-truth soft
shadows), the first sample in index order of each of ``--objects``.

Per sample four height maps: the contact line, the learned predictor (shipped
weights, ``contact="ground"``), ``auto``, and *edited*: the learned map after
``pixgraph.PixelHeightEdit`` with what a user would do in at most three drags:
up to three contact points placed where the object really touches the ground
(the simulated user: the lowest true-contact pixel — true height < 1 px — in each
of up to three equal column bins of those pixels), ``contact_mode`` shift or
upright, whichever gives the lower shadow error (the user sees the shadow).
Shadows: ``soft:64`` with each map vs the renderer's ground truth (RMSE over the
visible background outside the cutout).
"""
from __future__ import annotations

import argparse
import os

import numpy as np

OBJECTS = ("named:teddy", "named:duck", "named:table", "named:mug", "named:bunny", "named:lego")


def simulated_contacts(true_h, mask, k=3):
    """Up to ``k`` contact points (u, v) [px] where the true height is < 1 px (module doc)."""
    ys, xs = np.nonzero(mask & (true_h < 1.0))
    if len(xs) == 0:
        ys, xs = np.nonzero(mask)
        keep = ys >= ys.max() - 1
        ys, xs = ys[keep], xs[keep]
    edges = np.linspace(xs.min(), xs.max() + 1, min(k, len(np.unique(xs))) + 1)
    pts = []
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (xs >= a) & (xs < b)
        if sel.any():
            i = np.argmax(np.where(sel, ys, -1))
            pts.append((xs[i] + 0.5, ys[i] + 1.0))       # the bottom edge of that pixel
    return pts


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.real_photos", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shadows", required=True)
    ap.add_argument("--objects", default=",".join(OBJECTS))
    ap.add_argument("--weights", default=None)
    ap.add_argument("--out", required=True, help="PNG contact sheet")
    ap.add_argument("--table", required=True, help="markdown table of the numbers")
    a = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import torch
    torch.set_num_threads(1)

    from pixgraph.device import Device
    from pixgraph_nodes.ops.height_edit import edit_pixel_height
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor

    from pixgraph_lab.datagen.dataset import sample_files
    from pixgraph_lab.evaluate import Method, prepared_sample
    from pixgraph_lab.metrics import shadow_metrics
    device = Device.open()
    soft = Method("soft:64", 1.0)
    pred = LearnedHeightPredictor(a.weights or WEIGHTS)
    want = a.objects.split(",")
    chosen = {}
    for f in sample_files(a.shadows):
        import json
        with np.load(f) as z:
            obj = json.loads(str(z["meta"]))["scene"]["object"]
        if obj in want and obj not in chosen:
            chosen[obj] = f
    rows, figs = [], []
    for obj in want:
        if obj not in chosen:
            continue
        s = prepared_sample(chosen[obj], device)
        mask = s["mask"]
        valid = ~mask & s["bg_valid"]
        g = s["shadow"].astype(np.float64)
        al = s["alpha"].astype(np.float32)
        rgba = np.concatenate([s["rgb"].astype(np.float32) * al[..., None], al[..., None]], 2)
        r = pred.predict_full(rgba)
        true = s["fg_height"].astype(np.float32)
        pts = simulated_contacts(true, mask)
        maps = {"true": true, "heuristic": r["heuristic"], "learned": r["height"]}
        conf = r["confidence"]
        maps["auto"] = r["auto_height"]

        def shadow(h):
            return np.clip(soft.predict(dict(s, fg_height=np.where(mask, h, 0).astype(np.float32))), 0, 1)

        best = None
        for mode in ("shift", "upright"):
            e = edit_pixel_height(r["height"], mask, pts, contact_mode=mode)
            sh = shadow(e)
            rm = shadow_metrics(sh, g, valid)["rmse"]
            if best is None or rm < best[0]:
                best = (rm, mode, e, sh)
        maps["edited"] = best[2]
        shadows = {k: (best[3] if k == "edited" else shadow(h)) for k, h in maps.items()}
        row = {"object": obj, "index": s["meta"]["index"], "contacts": len(pts), "mode": best[1],
               "confidence": conf}
        for k in maps:
            row[f"mae_{k}"] = float(np.abs(maps[k][mask] - true[mask]).mean()) if k != "true" else 0.0
            row[f"rmse_{k}"] = shadow_metrics(shadows[k], g, valid)["rmse"]
        rows.append(row)
        figs.append((obj, s, g, maps, shadows, pts))
    # contact sheet: per sample, ground truth composite then each map's shadow, and the heights
    keys = ["true", "heuristic", "learned", "auto", "edited"]
    fig, axes = plt.subplots(2 * len(figs), len(keys) + 1, figsize=(2.0 * (len(keys) + 1), 4.0 * len(figs)))
    for i, (obj, s, g, maps, shadows, pts) in enumerate(figs):
        al = s["alpha"].astype(np.float32)[..., None]
        col = np.clip(s["rgb"].astype(np.float32), 0, 1) ** (1 / 2.2)

        def comp(d):
            bg = 0.8 * (1 - d)[..., None] * np.ones(3)
            return col * al + bg * (1 - al)
        axes[2 * i, 0].imshow(comp(g))
        axes[2 * i, 0].set_title(f"{obj[6:]}: rendered", fontsize=8)
        axes[2 * i + 1, 0].imshow(al[..., 0], cmap="gray")
        for (u, v) in pts:
            axes[2 * i + 1, 0].plot(u - 0.5, v - 0.5, "r+", ms=8)
        axes[2 * i + 1, 0].set_title("contact handles", fontsize=8)
        vmax = float(maps["true"].max())
        for j, k in enumerate(keys):
            axes[2 * i, j + 1].imshow(comp(shadows[k]))
            rr = [r for r in rows if r["object"] == obj][0]
            axes[2 * i, j + 1].set_title(f"{k}: RMSE {rr['rmse_' + k]:.3f}", fontsize=8)
            axes[2 * i + 1, j + 1].imshow(np.where(s["mask"], maps[k], np.nan), cmap="viridis", vmin=0, vmax=vmax)
            axes[2 * i + 1, j + 1].set_title(f"h {k}" + ("" if k == "true" else f": MAE {rr['mae_' + k]:.1f}"),
                                             fontsize=8)
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    os.makedirs(os.path.dirname(a.out) or ".", exist_ok=True)
    fig.savefig(a.out, dpi=60)
    lines = ["| object | index | height MAE px: heuristic / learned / auto / edited | soft:64 RMSE: true / "
             "heuristic / learned / auto / edited | edit (contact points, mode) | confidence |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        c = "n/a" if r["confidence"] is None else f"{r['confidence']:.2f}"
        lines.append(f"| {r['object'][6:]} | {r['index']} | {r['mae_heuristic']:.1f} / {r['mae_learned']:.1f} / "
                     f"{r['mae_auto']:.1f} / {r['mae_edited']:.1f} | {r['rmse_true']:.4f} / "
                     f"{r['rmse_heuristic']:.4f} / {r['rmse_learned']:.4f} / {r['rmse_auto']:.4f} / "
                     f"{r['rmse_edited']:.4f} | {r['contacts']}, {r['mode']} | {c} |")
    text = "\n".join(lines) + "\n"
    os.makedirs(os.path.dirname(a.table) or ".", exist_ok=True)
    with open(a.table, "w") as fh:
        fh.write(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
