"""Choose the learned height predictor's inference options on the validation split.

    python -m pixgraph_lab.height.inference_study --heights data/height/val --out runs/height_inference
    python -m pixgraph_lab.height.inference_study --heights data/height/val --out runs/height_inference --ship
    python -m pixgraph_lab.height.inference_study --heights data/height/test \\
        --shadows data/wall_test64 --out runs/height_inference_test     # report only, never a choice

``LearnedHeightPredictor.predict`` has two options that need no retraining
(``nodes/ops/learned_height.py``): ``flip_average`` (also read the mirrored crop,
average) and ``heuristic_detail`` (add back the detail of the contact-line
channel that the network's 64^2 size loses). Every combination is scored with
``evaluate.eval_heights`` (full-size pixel-height MAE [px] per sample over the
object's pixels, averaged) and, with ``--shadows``, ``evaluate.eval_shadows``
(soft-shadow RMSE against the renderer's ground truth).

The rule, fixed before any number was seen: the combination with the lowest mean
height MAE on the validation split (``generate --split val``: objects never
trained on) wins; a more expensive one (flip_average doubles the network's time)
must beat a cheaper one by more than 1 %. ``--ship`` refuses a split other than
``val`` and writes the choice into the shipped checkpoint's config
(``config["inference"]``, read by the predictor) and its provenance
``cutout_height.json`` (``inference``: the rule and the validation table).
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

VARIANTS = [(False, False), (False, True), (True, False), (True, True)]   # (flip_average, heuristic_detail)
RULE = ("lowest mean pixel-height MAE on the validation split (objects never trained on); "
        "flip_average (2x the network's time) must beat the cheaper choice by more than 1 %")


def name(flip: bool, detail: bool) -> str:
    return "+".join([k for k, on in (("flip_average", flip), ("heuristic_detail", detail)) if on]) or "plain"


def choose(maes: dict) -> tuple[bool, bool]:
    """The rule above on {(flip, detail): mean MAE}."""
    best = min((k for k in maes if not k[0]), key=maes.get)            # the cheap ones
    flip_best = min((k for k in maes if k[0]), key=maes.get, default=None)
    if flip_best is not None and maes[flip_best] < 0.99 * maes[best]:
        return flip_best
    return best


def group_means(rows, key):
    sel = {"all": lambda r: True, "upright": lambda r: r.get("pose", "upright") == "upright",
           "not upright": lambda r: r.get("pose") != "upright"}
    return {g: float(np.mean([r[key] for r in rows if f(r)])) for g, f in sel.items()
            if any(f(r) for r in rows)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.inference_study", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--heights", required=True, help="a pixgraph_lab.height.generate split folder")
    ap.add_argument("--shadows", default=None, help="a ground-truth benchmark folder (report only)")
    ap.add_argument("--weights", default=None, help="checkpoint (default: the shipped weights)")
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--out", required=True)
    ap.add_argument("--ship", action="store_true", help="write the choice into the shipped weights")
    a = ap.parse_args(argv)
    if a.ship and os.path.basename(os.path.normpath(a.heights)) != "val":
        ap.error("--ship chooses on the validation split only (--heights .../val)")
    if a.ship and a.weights:
        ap.error("--ship sets the shipped weights' options: leave out --weights")
    import torch
    torch.set_num_threads(1)
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor

    from .evaluate import _write, eval_heights, eval_shadows
    weights = a.weights or WEIGHTS
    os.makedirs(a.out, exist_ok=True)
    maes, lines, shadow_lines = {}, [], []
    for flip, detail in VARIANTS:
        pred = LearnedHeightPredictor(weights, flip_average=flip, heuristic_detail=detail)
        rows = eval_heights(a.heights, pred, a.limit)
        _write(os.path.join(a.out, f"heights_{name(flip, detail)}.csv"), rows)
        g = group_means(rows, "learned_mae_px")
        h = group_means(rows, "heuristic_mae_px")
        maes[flip, detail] = g["all"]
        ms = float(np.median([r["ms"] for r in rows]))
        lines.append(f"| {name(flip, detail)} | {len(rows)} | {g['all']:.3f} | {g.get('upright', np.nan):.3f} | "
                     f"{g.get('not upright', np.nan):.3f} | {h['all']:.3f} | {ms:.1f} |")
        if a.shadows:
            srows = eval_shadows(a.shadows, pred, limit=a.limit)
            _write(os.path.join(a.out, f"shadows_{name(flip, detail)}.csv"), srows)
            m = lambda k, sel=lambda r: True: float(np.mean([r[k] for r in srows if sel(r)]))  # noqa: E731
            urdf = lambda r: r["group"] != "figure (upright)"  # noqa: E731
            shadow_lines.append(
                f"| {name(flip, detail)} | {len(srows)} | {m('rmse_true'):.4f} | {m('rmse_learned'):.4f} | "
                f"{m('rmse_heuristic'):.4f} | {m('rmse_learned') / m('rmse_true') - 1:+.1%} | "
                f"{m('rmse_learned', urdf) / m('rmse_heuristic', urdf) - 1:+.1%} |")
    chosen = choose(maes)
    table = ("| inference | n | MAE px all | upright | not upright | heuristic MAE px | median ms |\n"
             "|---|---|---|---|---|---|---|\n" + "\n".join(lines) + "\n")
    text = [f"weights: {weights}\nsplit: {a.heights}\n", table]
    if shadow_lines:
        text.append("\n| inference | n | RMSE true h | RMSE learned h | RMSE heuristic h | learned / true | "
                    "learned vs heuristic (urdf) |\n|---|---|---|---|---|---|---|\n"
                    + "\n".join(shadow_lines) + "\n")
    text.append(f"\nrule: {RULE}\nchosen by the rule: {name(*chosen)}\n")
    report = "\n".join(text)
    with open(os.path.join(a.out, "report.md"), "w") as fh:
        fh.write(report)
    print(report)
    if a.ship:
        inference = {"flip_average": chosen[0], "heuristic_detail": chosen[1]}
        ck = torch.load(weights, map_location="cpu", weights_only=True)
        cfg = json.loads(ck["config"]) if isinstance(ck["config"], str) else dict(ck["config"])
        cfg["inference"] = inference
        ck["config"] = json.dumps(cfg)
        torch.save(ck, WEIGHTS)
        prov_path = WEIGHTS.with_suffix(".json")
        prov = json.loads(prov_path.read_text()) if prov_path.exists() else {}
        prov["inference"] = dict(inference, rule=RULE, command="python -m pixgraph_lab.height.inference_study "
                                 + " ".join(argv if argv is not None else sys.argv[1:]),
                                 validation=table)
        prov_path.write_text(json.dumps(prov, indent=1) + "\n")
        print(f"wrote inference {inference} into {WEIGHTS} and {prov_path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
