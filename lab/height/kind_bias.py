"""Where the learned map's error lies, per kind: signed and absolute errors over the
object's pixels divided by its box height, for the learned map and the contact line,
and the learned map's signed error over the upper and the lower half of the box
(docs/height-record.md, "Measured: a soup of the eleventh's runs": the kinds where
the learned map loses to the contact line).

    python -m pixgraph_lab.height.kind_bias --heights data/hreal/u4_heldout3 data/hreal/u5_heldout3 \\
        --kinds suitcase tent pram

A positive signed error: the map is too tall there (its ground point lies nearer the
camera than the true one). Every file of the folders whose object's last name part is
one of ``--kinds`` (all kinds when not given) is predicted with the checkpoint's
settings (``predict_full``: pinned and foot-snapped, the contact line under the same
constraint).
"""
from __future__ import annotations

import argparse
import collections

import numpy as np


def kind_errors(true: np.ndarray, learned: np.ndarray, contact: np.ndarray, mask: np.ndarray) -> dict:
    """One cutout's errors [box heights]: ``signed_learned``, ``signed_contact``,
    ``abs_learned``, ``abs_contact`` (means over the mask), ``signed_upper`` /
    ``signed_lower`` (the learned map's mean signed error over the mask's rows in the
    upper / lower half of its box)."""
    m = np.asarray(mask, bool)
    rows = np.nonzero(m)[0]
    top, bot = int(rows.min()), int(rows.max())
    bh = float(bot - top + 1)
    t, hl, hc = true[m], learned[m], contact[m]
    upper = (rows - top) < 0.5 * (bot - top)
    dl = (hl - t) / bh
    return {"signed_learned": float(dl.mean()), "signed_contact": float(((hc - t) / bh).mean()),
            "abs_learned": float(np.abs(dl).mean()), "abs_contact": float((np.abs(hc - t) / bh).mean()),
            "signed_upper": float(dl[upper].mean()) if upper.any() else float("nan"),
            "signed_lower": float(dl[~upper].mean()) if (~upper).any() else float("nan")}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.kind_bias", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", default=None, help="checkpoint (default: the shipped one)")
    ap.add_argument("--heights", nargs="+", required=True)
    ap.add_argument("--kinds", nargs="*", default=None)
    a = ap.parse_args(argv)
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor

    from .evaluate import height_files, read_height_sample
    pred = LearnedHeightPredictor(a.weights or WEIGHTS)
    by = collections.defaultdict(list)
    for d in a.heights:
        for f in height_files(d):
            meta, rgba, true, mask = read_height_sample(f)
            kind = meta["object"].split("/")[-1]
            if a.kinds and kind not in a.kinds:
                continue
            r = pred.predict_full(rgba)
            by[kind].append(kind_errors(true, r["height"], r["heuristic"], mask))
    print("| kind | n | signed: learned / contact line | learned: upper / lower half | "
          "MAE: learned / contact line |\n|---|---|---|---|---|")
    for kind in sorted(by):
        e = {k: np.nanmean([x[k] for x in by[kind]]) for k in by[kind][0]}
        print(f"| {kind} | {len(by[kind])} | {e['signed_learned']:+.3f} / {e['signed_contact']:+.3f} | "
              f"{e['signed_upper']:+.3f} / {e['signed_lower']:+.3f} | {e['abs_learned']:.3f} / {e['abs_contact']:.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
