"""Choose the contact pin's fade on the validation split (docs/height-record.md, "Pin rule").

    python -m pixgraph_lab.height.pin_study --weights runs/height4/best.pt --heights data/hreal/val \
        --out runs/pin_study [--write]

For each candidate (``constant``, fade 0.25, fade 0.5) and for no pin at all
(``free``, reported only), the mean full-size pixel-height MAE of
``LearnedHeightPredictor.predict`` over the split's samples, and the median
foot error (mean |predicted - true| over the contact pixels). The candidate with
the lowest MAE wins; ``--write`` stores it in the checkpoint's
``config["inference"]["pin_fade"]`` (None = constant) in place.
"""
from __future__ import annotations

import numpy as np

CANDIDATES = {"constant": None, "fade 0.25": 0.25, "fade 0.5": 0.5}


def main(argv=None) -> int:
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor, contact_band, pin_contact

    from .evaluate import height_files, read_height_sample, study_args, write_inference, write_report
    a = study_args("python -m pixgraph_lab.height.pin_study", __doc__, argv)
    pred = LearnedHeightPredictor(a.weights, pin_fade=None)
    res = {k: [] for k in ["free", *CANDIDATES]}
    foot = {k: [] for k in res}
    files = height_files(a.heights, a.limit)
    for f in files:
        _, rgba, true, mask = read_height_sample(f)
        m = rgba[..., 3] > 0.5
        free = pred.predict(rgba, contact="free")
        band = contact_band(m) & mask
        maps = {"free": free} | {k: pin_contact(free, m, fade=v) for k, v in CANDIDATES.items()}
        for k, h in maps.items():
            res[k].append(float(np.abs(h[mask] - true[mask]).mean()))
            if band.any():
                foot[k].append(float(np.abs(h[band] - true[band]).mean()))
    lines = [f"weights {a.weights}, {len(files)} samples of {a.heights}", "",
             "| pin | MAE px | median foot error px |", "|---|---|---|"]
    for k in res:
        lines.append(f"| {k} | {np.mean(res[k]):.3f} | {np.median(foot[k]):.3f} |")
    best = min(CANDIDATES, key=lambda k: np.mean(res[k]))
    lines += ["", f"chosen: {best}"]
    write_report(a.out, "pin_study.md", lines)
    if a.write:
        write_inference(a.weights, pin_fade=CANDIDATES[best],
                        pin_study={k: float(np.mean(v)) for k, v in res.items()})
        print(f"wrote pin_fade={CANDIDATES[best]} into {a.weights}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
