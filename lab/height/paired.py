"""Two ``evaluate_real`` runs on the same samples, compared per sample (docs/height-record.md,
"Measured: more kinds on a lent GPU": what the new kinds add, per kind).

    python -m pixgraph_lab.height.paired runs/u_h8b runs/u_h8a
    python -m pixgraph_lab.height.paired runs/u_h8b          # against its own --baseline column
    python -m pixgraph_lab.height.paired runs/heldout_h8b --exclude heldout/guitar

Reads ``A/heights.csv`` and ``B/heights.csv`` (the same samples in the same order:
checked by their ``object`` column) and prints, over all samples and per ``object``
(kind), n and the mean pixel-height MAE [px] of A's learned map, B's (or, with one
run, its ``mae_baseline``: the checkpoint given to ``--baseline``) and the contact
line, and the share of samples on which each learned map beats the contact line;
then the mean of the paired differences A - B [px] with its 95 % percentile
bootstrap interval (10,000 resamples of the samples, seed 0:
``scale_study.interval``). ``--exclude OBJECT`` (repeatable) leaves that kind's
samples out of everything.
"""
from __future__ import annotations

import argparse
import os

import numpy as np


def compare(a_rows, b_rows=None):
    """(table rows, (mean, lower, upper) of A - B): a row per group ("all", then each
    object in sorted order) as (group, n, A MAE, B MAE, contact line MAE, A beats the
    contact line [share], B beats it [share]); B is ``b_rows``' learned map or, without
    it, ``a_rows``' baseline column."""
    from .scale_study import interval
    if b_rows is None:
        b = np.array([r["mae_baseline"] for r in a_rows], float)
    else:
        if [r["object"] for r in a_rows] != [r["object"] for r in b_rows]:
            raise ValueError("the two runs are not on the same samples (their object columns differ)")
        b = np.array([r["mae_learned"] for r in b_rows], float)
    a = np.array([r["mae_learned"] for r in a_rows], float)
    h = np.array([r["mae_heuristic"] for r in a_rows], float)
    obj = np.array([r["object"] for r in a_rows])
    rows = []
    for g in ["all"] + sorted(set(obj)):
        s = np.ones(len(a), bool) if g == "all" else obj == g
        rows.append((g, int(s.sum()), a[s].mean(), b[s].mean(), h[s].mean(),
                     float((a[s] < h[s]).mean()), float((b[s] < h[s]).mean())))
    return rows, (float((a - b).mean()), *interval(a - b))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.paired", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("a", help="an evaluate_real output folder (its heights.csv)")
    ap.add_argument("b", nargs="?", help="another on the same samples; without it, A's baseline column")
    ap.add_argument("--exclude", action="append", default=[], metavar="OBJECT",
                    help="leave out the samples of this object column value (e.g. heldout/guitar)")
    args = ap.parse_args(argv)
    from .evaluate_real import _read
    a_rows = _read(os.path.join(args.a, "heights.csv"))
    b_rows = _read(os.path.join(args.b, "heights.csv")) if args.b else None
    keep = [r["object"] not in args.exclude for r in a_rows]
    a_rows = [r for r, k in zip(a_rows, keep) if k]
    if b_rows is not None:
        b_rows = [r for r, k in zip(b_rows, keep) if k] if len(b_rows) == len(keep) else b_rows
    rows, (m, lo, hi) = compare(a_rows, b_rows)
    bn = args.b or f"{args.a} (baseline)"
    ex = f"; without {', '.join(args.exclude)}" if args.exclude else ""
    print(f"A = {args.a}, B = {bn}; MAE in px{ex}\n")
    print("| kind | n | A | B | contact line | A beats the contact line | B beats it |\n|---|---|---|---|---|---|---|")
    for g, n, ma, mb, mh, wa, wb in rows:
        print(f"| {g} | {n} | {ma:.3f} | {mb:.3f} | {mh:.3f} | {100 * wa:.1f} % | {100 * wb:.1f} % |")
    print(f"\nA - B: {m:+.3f} px, 95 % paired bootstrap interval {lo:+.3f} to {hi:+.3f} (10,000 resamples, seed 0)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
