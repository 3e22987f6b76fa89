"""Choose the foot snap on the validation split (docs/height-record.md, "Foot rule").

    python -m pixgraph_lab.height.foot_study --weights runs/height5/best.pt --heights data/hreal/val \\
        --out runs/foot_study [--write]

The checkpoint's pinned map (``LearnedHeightPredictor.predict``, ``contact="ground"``,
its own pin fade, no snap) is computed once per sample; then for every candidate
``(tol, hull)`` of ``learned_height.snap_feet`` (tol in {off, 1, 2, 3, 4} px, hull
on / off) the mean full-size pixel-height MAE over the samples, and the median
over the samples that show a foot of the foot error (the mean predicted height
over the pixels whose true height is < 1 px, as in ``evaluate_real``). The rule:
the lowest median foot error among the candidates whose MAE is at most 1 %
above the unsnapped one (ties: the smaller tol, then hull on). ``--write`` stores
it in the checkpoint's ``config["inference"]["foot_snap"]`` (None = off) in place.
"""
from __future__ import annotations

import numpy as np

TOLS = (1.0, 2.0, 3.0, 4.0)


def candidates():
    """[(name, None | {"tol", "hull"})], "off" first."""
    out = [("off", None)]
    for t in TOLS:
        for hull in (True, False):
            out.append((f"tol {t:g}{' hull' if hull else ''}", {"tol": t, "hull": hull}))
    return out


def choose(mae: dict, foot: dict) -> str:
    """The rule (module doc) on {name: mean MAE} and {name: median foot error}."""
    ok = [k for k in mae if mae[k] <= 1.01 * mae["off"]]
    order = {k: i for i, (k, _) in enumerate(candidates())}
    return min(ok, key=lambda k: (round(foot[k], 6), order[k]))


def main(argv=None) -> int:
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor, snap_feet

    from .evaluate import height_files, read_height_sample, study_args, write_inference, write_report
    from .evaluate_real import _errs
    a = study_args("python -m pixgraph_lab.height.foot_study", __doc__, argv)
    pred = LearnedHeightPredictor(a.weights, foot_snap=None)
    cands = candidates()
    mae = {k: [] for k, _ in cands}
    foot = {k: [] for k, _ in cands}
    files = height_files(a.heights, a.limit)
    for f in files:
        _, rgba, true, mask = read_height_sample(f)
        m = rgba[..., 3] > 0.5
        feet = mask & m & (true < 1.0)
        h0 = pred.predict(rgba)
        for k, c in cands:
            h = h0 if c is None else snap_feet(h0, m, c["tol"], c["hull"])
            e_mae, e_foot = _errs(h, true, mask, feet)
            mae[k].append(e_mae)
            if feet.any():
                foot[k].append(e_foot)
    mmae = {k: float(np.mean(v)) for k, v in mae.items()}
    mfoot = {k: float(np.median(v)) for k, v in foot.items()}
    best = choose(mmae, mfoot)
    lines = [f"weights {a.weights}, {len(files)} samples of {a.heights} ({len(foot['off'])} show a foot)", "",
             "| foot snap | MAE px | median foot error px | mean foot error px |", "|---|---|---|---|"]
    for k, _ in cands:
        lines.append(f"| {k} | {mmae[k]:.3f} | {mfoot[k]:.3f} | {np.mean(foot[k]):.3f} |")
    lines += ["", f"chosen: {best}"]
    write_report(a.out, "foot_study.md", lines)
    if a.write:
        write_inference(a.weights, foot_snap=dict(cands)[best],
                        foot_study={k: [mmae[k], mfoot[k]] for k in mmae})
        print(f"wrote foot_snap={dict(cands)[best]} into {a.weights}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
