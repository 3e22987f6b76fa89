"""Chart: SSN++ model size against accuracy and time (issue: SSN++ goals).

    python benchmarks/ssn_size_chart.py --eval data/wall_test/eval_ablation/table.csv \\
        --eval data/wall_test/eval_sweep/table.csv \\
        --bench out/ssn_bench_all.json --out docs/img/ssn_size.png \\
        --model ssnpp_b4 --model ssnpp --model ssnpp_b16

Reads the accuracy of each model from an evaluation table
(``pixgraph_lab.evaluate``'s ``table.csv``, method ``pixgraph_lab.ssn.methods:run_<name>``),
its median ms per sample from ``benchmarks/ssn_bench.py --data ... --json`` and its
parameters / FLOPs from ``runs/<name>/model.json`` (``$PIXGRAPH_SSN_RUNS``).
Left panel: parameters against RMSE; right panel: ms per sample against RMSE,
with every ``soft:N`` row of both files as the classical curve. Prints the
numbers it plots.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import pathlib
import sys

PREFIX = "pixgraph_lab.ssn.methods:run_"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--eval", action="append", required=True,
                    help="evaluation table.csv (repeat to merge tables of the same benchmark)")
    ap.add_argument("--bench", required=True, help="ssn_bench.py --json output")
    ap.add_argument("--model", action="append", required=True, help="run folder name, smallest first")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    runs = pathlib.Path(os.environ.get("PIXGRAPH_SSN_RUNS", "runs"))
    acc = {r["method"]: r for path in a.eval for r in csv.DictReader(open(path))}
    bench = json.loads(pathlib.Path(a.bench).read_text())
    ms = {k: v["median"] for k, v in bench["ms"].items()}

    models = []
    for name in a.model:
        spec = PREFIX + name
        meta = json.loads((runs / name / "model.json").read_text())
        missing = [what for what, table in (("evaluation table", acc), ("benchmark", ms)) if spec not in table]
        if missing:
            raise SystemExit(f"{spec}: not in the {' or '.join(missing)}")
        models.append(dict(name=name, params=meta["params"], gflops=meta["gflops_256"], base=meta["config"]["base"],
                           steps=meta["steps"], rmse=float(acc[spec]["rmse"]), ms=ms[spec]))
    soft = sorted((int(k.split(":")[1]), ms[k], float(acc[k]["rmse"])) for k in ms if k.startswith("soft:") and k in acc)

    print(f"{'model':12s} {'base':>4s} {'params':>9s} {'GFLOP':>6s} {'steps':>6s} {'RMSE':>7s} {'ms':>7s}")
    for m in models:
        print(f"{m['name']:12s} {m['base']:4d} {m['params']:9,d} {m['gflops']:6.2f} {m['steps']:6d} "
              f"{m['rmse']:7.4f} {m['ms']:7.1f}")
    for n, t, r in soft:
        print(f"{'soft:' + str(n):12s} {'':4s} {'':9s} {'':6s} {'':6s} {r:7.4f} {t:7.1f}")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(10, 4))
    ax1.plot([m["params"] for m in models], [m["rmse"] for m in models], "o-", color="C0")
    for m in models:
        ax1.annotate(f"base {m['base']}: {m['gflops']:.2f} GFLOP\n{m['steps']} steps", (m["params"], m["rmse"]),
                     textcoords="offset points", xytext=(-30, 10), fontsize=8)
    ax1.set_xscale("log")
    ax1.margins(x=0.15, y=0.15)
    ax1.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax1.set_xlabel("parameters")
    ax1.set_ylabel("RMSE (wall benchmark)")
    ax1.set_title("SSN++ size vs accuracy\n(about equal training time, one CPU core each)", fontsize=10)
    ax2.plot([m["ms"] for m in models], [m["rmse"] for m in models], "o-", color="C0", label="SSN++ (base 4/8/16)")
    for i, m in enumerate(models):
        ax2.annotate(f"base {m['base']}", (m["ms"], m["rmse"]), textcoords="offset points",
                     xytext=(6, 6 - 12 * (i % 2)), fontsize=8)
    if soft:
        ax2.plot([t for _, t, _ in soft], [r for _, _, r in soft], "s--", color="C1", label="classical soft:N")
        for n, t, r in soft:
            ax2.annotate(str(n), (t, r), textcoords="offset points", xytext=(4, -10), fontsize=8, color="C1")
    ax2.axvline(50, color="grey", lw=0.8, ls=":")
    ax2.text(50, ax2.get_ylim()[1], " 50 ms goal", va="top", fontsize=8, color="grey")
    ax2.set_xscale("log")
    ax2.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax2.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g}"))
    ax2.set_xticks([20, 30, 50, 100])
    ax2.set_xlabel("ms per 256² sample (median, whole prediction)")
    ax2.set_ylabel("RMSE (wall benchmark)")
    ax2.set_title("speed vs accuracy", fontsize=10)
    ax2.legend(fontsize=8)
    fig.text(0.5, -0.02, bench.get("machine", ""), ha="center", fontsize=7, color="grey")
    fig.tight_layout()
    pathlib.Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(a.out, dpi=110, bbox_inches="tight")
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
