"""Validation RMSE of several training runs against optimiser steps, in one chart.

    python -m pixgraph_lab.ssn.curves runs/ssg runs/sparse runs/reldist runs/ssnpp \\
        --out docs/img/ssn_ablation_val.png

Each run folder is one written by ``pixgraph_lab.ssn.train`` (its ``log.csv``);
the legend names the folder, the variant and the final validation RMSE. Steps,
not minutes, are on the x axis, because runs that shared the machine with other
jobs took longer per step.
"""
from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("runs", nargs="+", type=pathlib.Path)
    ap.add_argument("--out", required=True, type=pathlib.Path)
    a = ap.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    for run in a.runs:
        log = run / "log.csv"
        if not log.exists():
            raise SystemExit(f"{run}: no log.csv (not a training run folder?)")
        rows = list(csv.DictReader(open(log)))
        meta = json.loads((run / "model.json").read_text()) if (run / "model.json").exists() else {}
        cfg = meta.get("config", {})
        label = f"{run.name} ({cfg.get('variant', '?')}, base {cfg.get('base', '?')})"
        if rows:
            label += f": {float(rows[-1]['val_rmse']):.4f}"
        ax.plot([int(r["step"]) for r in rows], [float(r["val_rmse"]) for r in rows], label=label)
    ax.set_xlabel("optimiser steps (batch 8)")
    ax.set_ylabel("validation RMSE")
    ax.set_ylim(top=0.12)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    a.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out, dpi=100)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
