"""Measure the shadow-method table that ``method: auto`` chooses from, and check it.

    python -m pixgraph_lab.auto_table --data data/wall_test --data data/ground_test \
        --out out/auto --table nodes/weights/shadow_methods.json --chart docs/img/auto_error_time.png

1. Evaluates every candidate method (``hard``, ``soft:4 .. soft:64``, ``ssn`` =
   the SoftShadowSSN node's computation) and the reference ``soft:256`` on every
   sample (``pixgraph_lab.evaluate``; per-sample rows cached in ``--out``,
   reused with ``--reuse``).
2. Measures each sample's table index the node's way (``choose.scene_features``:
   softness, receiver kind) and its cost.
3. Two-fold check: fits the table on the even-indexed samples and applies
   ``auto`` to the odd ones, and the other way round, for each ``--target``;
   reports how often auto's RMSE exceeds the target, its mean RMSE and mean
   time (the chosen method's measured time plus the features'), next to every
   fixed method.
4. Writes the table fitted on all samples (``--table``) with its provenance,
   and the error-vs-time chart (``--chart``).

Times: the evaluator's per-sample ms are measured one method after another on
a shared machine; ``--times`` replaces them by medians measured interleaved
(``benchmarks/ssn_bench.py --data ... --json``, see docs/auto.md).
"""
from __future__ import annotations

import argparse
import csv
import datetime
import json
import os
import sys
import time

import numpy as np

CANDIDATES = ("hard", "soft:4", "soft:8", "soft:16", "soft:32", "soft:64", "ssn")
REFERENCE = "soft:256"
SPECS = {"ssn": "pixgraph_lab.ssn.methods:node"}
#: softness bin edges (radius / distance); the benchmarks' lights span 0.015-0.45, log-uniform
SOFTNESS_EDGES = (0.0, 0.035, 0.07, 0.15, 10.0)
TARGETS = (0.03, 0.04, 0.05, 0.06, 0.08, 0.1, 0.12, 0.15)


def spec(m: str) -> str:
    return SPECS.get(m, m)


def measure(data_dirs, out: str, reuse: bool, progress: bool = True, refresh=()) -> list[dict]:
    """One record per sample: data, index, softness, receiver, feature_ms, rmse{m}, ms{m}."""
    from pixgraph.device import Device
    from pixgraph_nodes.ops.choose import scene_features
    from .datagen.dataset import sample_files
    from .evaluate import evaluate, prepared_sample, write_csv

    device = Device.open()
    methods = list(CANDIDATES) + [REFERENCE]
    records = []
    for d in data_dirs:
        name = os.path.basename(os.path.normpath(d))
        path = os.path.join(out, f"rows_{name}.csv")
        if reuse and os.path.exists(path):
            with open(path) as fh:
                rows = list(csv.DictReader(fh))
            if refresh:       # recompute these methods, keep the others' rows
                again = {spec(m) for m in refresh}
                rows = [r for r in rows if r["method"] not in again]
                rows += evaluate(d, sorted(again), device=device, progress=progress)
                write_csv(path, rows)
        else:
            rows = evaluate(d, [spec(m) for m in methods], device=device, progress=progress)
            write_csv(path, rows)
        by = {}
        for r in rows:
            by.setdefault(int(r["index"]), {})[r["method"]] = r
        for f in sample_files(d):
            s = prepared_sample(f, device)
            idx = int(s["meta"]["index"])
            if idx not in by:
                continue
            m = s["mask"].astype(np.float32)
            scene_features(device, m, s["fg_height"], s["bg_height"], s["light"], s["camera"])  # warm
            t0 = time.perf_counter()
            softness, receiver, _ = scene_features(device, m, s["fg_height"], s["bg_height"], s["light"],
                                                   s["camera"])
            fms = 1e3 * (time.perf_counter() - t0)
            rec = {"data": name, "index": idx, "softness": softness, "receiver": receiver, "feature_ms": fms,
                   "relative_radius": float(by[idx][spec(REFERENCE)]["relative_radius"]),
                   "rmse": {mm: float(by[idx][spec(mm)]["rmse"]) for mm in methods},
                   "ms": {mm: float(by[idx][spec(mm)]["ms"]) for mm in methods}}
            records.append(rec)
    return records


def features(sample):
    """``choose.scene_features`` as an evaluation method (for timing it next to the
    methods with ``benchmarks/ssn_bench.py``); returns its hard shadow's darkness."""
    from pixgraph_nodes.ops.choose import scene_features
    _, _, lit = scene_features(sample["device"], sample["mask"].astype(np.float32), sample["fg_height"],
                               sample["bg_height"], sample["light"], sample["camera"])
    return 1.0 - lit


def use_times(records, path: str) -> None:
    """Replace every record's ms by the interleaved medians of ``ssn_bench.py --json``
    (the evaluator times methods one after another, under whatever load there was)."""
    with open(path) as fh:
        ms = json.load(fh)["ms"]
    med = {m: ms[spec(m)]["median"] for m in list(CANDIDATES) + [REFERENCE]}
    feat = ms["pixgraph_lab.auto_table:features"]["median"]
    for r in records:
        r["ms"] = dict(med)
        r["feature_ms"] = feat


def _stats(vals) -> dict:
    v = np.asarray(vals, np.float64)
    if v.size == 0:
        return {"n": 0, "mean": float("inf"), "p90": float("inf")}
    return {"n": int(v.size), "mean": float(v.mean()), "p90": float(np.percentile(v, 90))}


def fit(records, methods=CANDIDATES) -> dict:
    """The table (see ``pixgraph_nodes.ops.choose``) from sample records."""
    edges = list(SOFTNESS_EDGES)
    cells = {}
    for rec_kind in ("wall", "ground"):
        rs = [r for r in records if r["receiver"] == rec_kind]
        bins = []
        for b in range(len(edges) - 1):
            rb = [r for r in rs if edges[b] <= r["softness"] < edges[b + 1]]
            bins.append({m: _stats([r["rmse"][m] for r in rb]) for m in methods})
        cells[rec_kind] = {"bins": bins, "all": {m: _stats([r["rmse"][m] for r in rs]) for m in methods}}
    ms = {m: float(np.median([r["ms"][m] for r in records])) for m in methods}
    return {"version": 1, "methods": list(methods), "softness_edges": edges, "cells": cells, "ms_256": ms,
            "feature_ms_256": float(np.median([r["feature_ms"] for r in records]))}


def apply_auto(table, records, target) -> list[dict]:
    from pixgraph_nodes.ops.choose import choose
    out = []
    for r in records:
        c = choose(table, r["softness"], r["receiver"], 256 * 256, target)
        out.append({"method": c.method, "rmse": r["rmse"][c.method], "ms": r["ms"][c.method] + r["feature_ms"],
                    "met": c.met})
    return out


def cross_check(records, targets):
    """Two-fold: fit on one parity of the sample index, apply to the other."""
    res = {}
    for t in targets:
        got = []
        for fold in (0, 1):
            table = fit([r for r in records if r["index"] % 2 == fold])
            got += apply_auto(table, [r for r in records if r["index"] % 2 != fold], t)
        res[t] = got
    return res


def report(records, res, targets) -> str:
    methods = list(CANDIDATES) + [REFERENCE]
    n = len(records)
    lines = [f"Held-out check (two-fold by sample index parity), {n} samples "
             f"({sum(r['receiver'] == 'wall' for r in records)} wall / "
             f"{sum(r['receiver'] == 'ground' for r in records)} ground receivers by `scene_features`).", "",
             "Fixed methods (mean RMSE, mean ms per sample at 256², and % of samples above each target):", "",
             "| method | mean RMSE | mean ms | " + " | ".join(f"> {t:g}" for t in targets) + " |",
             "|---|---|---|" + "---|" * len(targets)]
    for m in methods:
        e = np.array([r["rmse"][m] for r in records])
        ms = np.mean([r["ms"][m] for r in records])
        lines.append(f"| {m} | {e.mean():.4f} | {ms:.1f} | "
                     + " | ".join(f"{100 * (e > t).mean():.0f}%" for t in targets) + " |")
    ref_e = np.mean([r["rmse"][REFERENCE] for r in records])
    ref_ms = np.mean([r["ms"][REFERENCE] for r in records])
    lines += ["", f"`auto` (chosen method's time + the features' time; reference {REFERENCE}: "
              f"RMSE {ref_e:.4f}, {ref_ms:.1f} ms):", "",
              "| max_rmse | % above target | mean RMSE | mean ms | speed-up vs soft:256 | target reachable | choices |",
              "|---|---|---|---|---|---|---|"]
    for t in targets:
        g = res[t]
        e = np.array([x["rmse"] for x in g])
        ms = np.mean([x["ms"] for x in g])
        counts = {}
        for x in g:
            counts[x["method"]] = counts.get(x["method"], 0) + 1
        ch = ", ".join(f"{k} {v}" for k, v in sorted(counts.items(), key=lambda kv: -kv[1]))
        lines.append(f"| {t:g} | {100 * (e > t).mean():.1f}% | {e.mean():.4f} | {ms:.1f} | {ref_ms / ms:.1f}x | "
                     f"{100 * np.mean([x['met'] for x in g]):.0f}% | {ch} |")
    return "\n".join(lines) + "\n"


def chart(records, res, targets, path: str) -> None:
    """Left: mean error vs mean time per method, auto's held-out results on top
    (one star per target). Right: how often each exceeds the target."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(11, 4.2), gridspec_kw={"width_ratios": [1.4, 1]})
    methods = list(CANDIDATES) + [REFERENCE]
    for m in methods:
        e = np.mean([r["rmse"][m] for r in records])
        ms = np.mean([r["ms"][m] for r in records])
        ax.scatter(ms, e, color="tab:green" if m == "ssn" else "tab:blue", s=30, zorder=3)
        ax.annotate(m, (ms, e), textcoords="offset points", xytext=(4, 4), fontsize=8)
    soft = [m for m in methods if m.startswith("soft:")]
    ax.plot([np.mean([r["ms"][m] for r in records]) for m in soft],
            [np.mean([r["rmse"][m] for r in records]) for m in soft], "-", color="tab:blue", lw=1, zorder=2)
    pts = {}
    for t in targets:
        key = (round(float(np.mean([x["ms"] for x in res[t]])), 3), round(float(np.mean([x["rmse"] for x in res[t]])), 5))
        pts.setdefault(key, []).append(t)
    xs, ys = zip(*pts)
    ax.plot(xs, ys, "*", color="tab:red", ms=12, zorder=4, label="auto, held out (label: max_rmse)")
    for (x, y), ts in pts.items():
        ax.annotate("/".join(f"{t:g}" for t in ts), (x, y), textcoords="offset points", xytext=(-8, -14),
                    fontsize=8, color="tab:red")
    ax.set_xscale("log")
    ax.set_xlabel("mean time per sample at 256² [ms] (log)")
    ax.set_ylabel("mean RMSE vs. Mitsuba ground truth")
    ax.set_title(f"error vs time, wall + ground samples (n={len(records)})", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    for m, style in (("soft:16", "b--"), ("soft:256", "b:"), ("ssn", "g--")):
        bx.plot(targets, [100 * np.mean([r["rmse"][m] > t for r in records]) for t in targets], style, label=m)
    bx.plot(targets, [100 * np.mean([x["rmse"] > t for x in res[t]]) for t in targets], "r-*", ms=9,
            label="auto (held out)")
    bx.axhline(10, color="gray", lw=1)
    bx.annotate("goal: 10 %", (targets[0], 11), fontsize=8, color="gray")
    bx.set_xlabel("max_rmse (target)")
    bx.set_ylabel("% of samples with RMSE above the target")
    bx.set_title("how often the target is exceeded", fontsize=9)
    bx.grid(True, alpha=0.3)
    bx.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.auto_table", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", action="append", required=True, help="benchmark folder (repeatable)")
    ap.add_argument("--out", default="out/auto")
    ap.add_argument("--table", default=None, help="write the table fitted on all samples here")
    ap.add_argument("--chart", default=None, help="error-vs-time chart (png)")
    ap.add_argument("--target", type=float, action="append", default=None)
    ap.add_argument("--reuse", action="store_true", help="reuse the per-sample rows in --out")
    ap.add_argument("--refresh", action="append", default=[], choices=list(CANDIDATES) + [REFERENCE],
                    help="with --reuse: measure this method again (repeatable)")
    ap.add_argument("--times", default=None,
                    help="ssn_bench.py --json output: use its interleaved median ms instead of the evaluator's")
    ap.add_argument("--no-progress", action="store_true")
    a = ap.parse_args(argv)
    targets = tuple(a.target or TARGETS)
    os.makedirs(a.out, exist_ok=True)
    records = measure(a.data, a.out, a.reuse, not a.no_progress, a.refresh)
    if a.times:
        use_times(records, a.times)
    with open(os.path.join(a.out, "records.json"), "w") as fh:
        json.dump(records, fh)
    res = cross_check(records, targets)
    text = report(records, res, targets)
    print(text)
    with open(os.path.join(a.out, "report.md"), "w") as fh:
        fh.write(text)
    if a.chart:
        chart(records, res, targets, a.chart)
    if a.table:
        sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "benchmarks"))
        table = fit(records)
        from pixgraph_lab.evaluate import load_sample  # noqa: F401  (package import check)
        try:
            from _machine import cpu_model
            machine = cpu_model()
        except ImportError:
            machine = "unknown"
        table["provenance"] = {
            "command": "python -m pixgraph_lab.auto_table " + " ".join(
                x for x in (argv if argv is not None else sys.argv[1:]) if x not in ("--reuse", "--no-progress")),
            "data": {d: sum(r["data"] == os.path.basename(os.path.normpath(d)) for r in records) for d in a.data},
            "date": datetime.date.today().isoformat(), "machine": machine,
            "note": "RMSE vs Mitsuba ground truth at 256^2; ms: median per sample on the shared CPU"}
        with open(a.table, "w") as fh:
            json.dump(table, fh, indent=1, sort_keys=True)
            fh.write("\n")
        print(f"wrote {a.table}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
