"""Evaluate soft-shadow methods on a ground-truth benchmark (paper Tables 1-2 style).

    python -m pixgraph_lab.evaluate --data data/wall_test --method soft:64 --method graph:my.yaml

Every table carries the baseline rows, measured on the same samples, whatever
``--method`` asks for: ``renderer_hard`` (the renderer's own hard shadow from the
light's centre), ``hard`` (our pixel-height hard shadow) and ``soft:4``,
``soft:16``, ``soft:64``, ``soft:256`` (the classical pixel-height soft shadow:
the average of hard shadows from N sunflower samples of the disk light), unless
``--no-baselines`` asks for the given methods only (to add one to an earlier
evaluation of the same folder: concatenate the two ``per_sample.csv``).

Method specs:

* ``renderer_hard``, ``hard``, ``soft:N`` — built in;
* ``module:function`` — a Python callable ``f(sample) -> darkness`` (float (H, W),
  1 = full shadow); ``sample`` is ``dataset.load_sample``'s dict plus ``light``
  (a ``nodes/ops/lights.Light``) and ``device`` (the OpenCL device);
* ``graph:path.yaml`` — a pixgraph graph run through ``pixgraph.session.Session``:
  the nodes named ``mask``, ``fg_height``, ``bg_height``, ``light``, ``camera``
  (whichever exist) are bound to the sample's values and the graph's output named
  ``darkness`` (else its first output) is the prediction.

Metrics (lab/metrics.py) per sample on darkness maps, over background pixels
outside the cutout (``valid = ~mask & bg_valid``: the composite covers the
cutout, and rays that hit no background — sky above a ground plane — have no
receiver), then averaged. Time: wall-clock ms per sample of the method call
(upload, trace, read back; the first call of each method, which builds OpenCL
programs, is excluded from the mean).

Writes ``<out>/table.md``, ``table.csv``, ``per_sample.csv`` and ``speed_accuracy.png``
(and the failure charts of ``failure.py`` unless ``--no-failure``).
"""
from __future__ import annotations

import argparse
import csv
import importlib
import os
import time

import numpy as np

from .datagen.dataset import load_sample, sample_files
from .failure import stroke_width
from .metrics import shadow_metrics

BASELINES = ("renderer_hard", "hard", "soft:4", "soft:16", "soft:64", "soft:256")
METRIC_NAMES = ("rmse", "rmse_s", "ssim", "zncc")


def light_of(sample: dict):
    from pixgraph_nodes.ops.lights import Light
    return Light("disk", position=tuple(float(x) for x in sample["light_center"]),
                 radius=float(sample["light_radius"]), normal=tuple(float(x) for x in sample["light_normal"]))


def prepared_sample(path, device) -> dict:
    """``load_sample(path)`` plus what methods read: ``light`` and ``device``."""
    s = load_sample(path)
    s["light"] = light_of(s)
    s["device"] = device
    return s


class Method:
    """A named predictor: ``predict(sample) -> darkness (H, W)``."""

    def __init__(self, spec: str, thickness: float = 1.0):
        self.spec = spec
        self.thickness = thickness
        self._session = None
        if spec == "renderer_hard":
            self._fn = lambda s: s["hard_shadow"].astype(np.float32)
        elif spec == "hard":
            self._fn = self._hard
        elif spec.startswith("soft:"):
            self.n = int(spec.split(":", 1)[1])
            if self.n < 1:
                raise ValueError(f"{spec}: need at least one light sample")
            self._fn = self._soft
        elif spec.startswith("graph:"):
            self.path = spec.split(":", 1)[1]
            if not os.path.exists(self.path):
                raise FileNotFoundError(f"{spec}: no graph file {self.path}")
            self._fn = self._graph
        elif ":" in spec:
            mod, fn = spec.split(":", 1)
            self._fn = getattr(importlib.import_module(mod), fn)
        else:
            raise ValueError(f"unknown method {spec!r}: renderer_hard, hard, soft:N, module:function "
                             f"or graph:path.yaml")

    def _hard(self, s):
        from pixgraph_nodes.ops.lights import light_point
        from pixgraph_nodes.ops.shadow import hard_shadow
        lit = hard_shadow(s["device"], s["mask"].astype(np.float32), s["fg_height"], s["bg_height"],
                          light_point(s["light"], s["camera"]), self.thickness)
        return 1.0 - lit

    def _soft(self, s):
        from pixgraph_nodes.ops.lights import disk_samples
        from pixgraph_nodes.ops.shadow import soft_shadow
        lit = soft_shadow(s["device"], s["mask"].astype(np.float32), s["fg_height"], s["bg_height"],
                          disk_samples(s["light"], s["camera"], self.n), self.thickness)
        return 1.0 - lit

    def _graph(self, s):
        from pixgraph.session import Session
        if self._session is None:
            self._session = Session(device=s["device"])
            self._graph_value = self._session.load(self.path)
        g = self._graph_value
        values = {"mask": s["mask"].astype(np.float32), "fg_height": s["fg_height"],
                  "bg_height": s["bg_height"], "light": s["light"], "camera": s["camera"]}
        bind = {k: v for k, v in values.items() if k in g.nodes}
        outs = self._session.run(g, bind=bind)
        if "darkness" in outs:
            return np.asarray(outs["darkness"], np.float32)
        return np.asarray(next(iter(outs.values())), np.float32)

    def predict(self, sample):
        out = np.asarray(self._fn(sample), np.float32)
        if out.shape != sample["shadow"].shape:
            raise ValueError(f"{self.spec}: prediction {out.shape} != ground truth {sample['shadow'].shape}")
        return out


def sample_factors(s: dict) -> dict:
    """Per-sample quantities the failure charts bin by."""
    meta = s["meta"]
    lt = meta["light"]
    return {"index": meta["index"], "background": meta["scene"]["background"], "object": meta["scene"]["object"],
            "elevation_deg": lt["elevation_deg"], "relative_radius": lt["relative_radius"],
            "wall_clearance": meta["scene"]["background_params"].get("clearance", float("nan")),
            "object_height": meta["scene"]["object_height"], "stroke_width": stroke_width(s["mask"]),
            "light_behind_camera": int(meta["light_uvhs"][3] < 0)}


def evaluate(data_dir: str, specs, limit: int = 0, thickness: float = 1.0, device=None, progress=True):
    """Run every method on every sample. Returns a list of per-sample row dicts."""
    from tqdm import tqdm
    files = sample_files(data_dir)
    if limit:
        files = files[:limit]
    if device is None:
        from pixgraph.device import Device
        device = Device.open()
    methods = [Method(sp, thickness) for sp in specs]
    warm = set()
    rows = []
    for f in tqdm(files, desc=f"evaluate {os.path.basename(os.path.normpath(data_dir))}", disable=not progress):
        s = prepared_sample(f, device)
        valid = ~s["mask"] & s["bg_valid"]
        g = s["shadow"].astype(np.float64)
        fac = sample_factors(s)
        for m in methods:
            if m.spec not in warm:          # build programs / sessions outside the timing
                m.predict(s)
                warm.add(m.spec)
            t0 = time.perf_counter()
            p = m.predict(s)
            ms = 1e3 * (time.perf_counter() - t0)
            row = dict(fac, method=m.spec, ms=ms, **shadow_metrics(np.clip(p, 0, 1), g, valid))
            rows.append(row)
    return rows


def summarize(rows, specs):
    out = []
    for sp in specs:
        rs = [r for r in rows if r["method"] == sp]
        if not rs:
            continue
        out.append({"method": sp, "n": len(rs), **{k: float(np.mean([r[k] for r in rs])) for k in METRIC_NAMES},
                    "ms": float(np.mean([r["ms"] for r in rs]))})
    return out


def markdown_table(summary, title: str) -> str:
    lines = [f"**{title}**", "", "| Method | RMSE ↓ | RMSE-s ↓ | SSIM ↑ | ZNCC ↑ | ms/sample | n |",
             "|---|---|---|---|---|---|---|"]
    for r in summary:
        lines.append(f"| {r['method']} | {r['rmse']:.4f} | {r['rmse_s']:.4f} | {r['ssim']:.4f} | "
                     f"{r['zncc']:.4f} | {r['ms']:.1f} | {r['n']} |")
    return "\n".join(lines) + "\n"


def background_table(rows, specs) -> str:
    """Mean RMSE per background kind and method (Markdown)."""
    kinds = sorted({r["background"] for r in rows})
    lines = ["| Method | " + " | ".join(f"{k} (n={len({r['index'] for r in rows if r['background'] == k})})"
                                       for k in kinds) + " |",
             "|---|" + "---|" * len(kinds)]
    for sp in specs:
        vals = [np.mean([r["rmse"] for r in rows if r["method"] == sp and r["background"] == k] or [np.nan])
                for k in kinds]
        lines.append(f"| {sp} | " + " | ".join(f"{v:.4f}" for v in vals) + " |")
    return "RMSE by background:\n\n" + "\n".join(lines) + "\n"


def write_csv(path, rows):
    if not rows:
        return
    keys = list(rows[0].keys())
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def speed_accuracy_chart(summary, path: str, title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6, 4))
    for r in summary:
        if r["method"] == "renderer_hard":     # read from file: no meaningful time, draw a level
            ax.axhline(r["rmse"], color="gray", ls="--", lw=1)
            ax.annotate("renderer hard shadow", (0.01, r["rmse"]), xycoords=("axes fraction", "data"),
                        textcoords="offset points", xytext=(0, 3), fontsize=8, color="gray")
            continue
        base = r["method"] in BASELINES
        ax.scatter(max(r["ms"], 1e-3), r["rmse"], marker="o" if base else "*", s=40 if base else 120)
        ax.annotate(r["method"], (max(r["ms"], 1e-3), r["rmse"]), textcoords="offset points", xytext=(4, 4),
                    fontsize=8)
    soft = [r for r in summary if r["method"].startswith("soft:")]
    soft.sort(key=lambda r: int(r["method"].split(":")[1]))
    if len(soft) > 1:
        ax.plot([max(r["ms"], 1e-3) for r in soft], [r["rmse"] for r in soft], "-", color="gray", lw=1, zorder=0)
    ax.set_xscale("log")
    ax.set_xlabel("time per sample [ms] (log)")
    ax.set_ylabel("RMSE vs. Mitsuba ground truth")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.evaluate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, help="benchmark folder (NNNNN.npz + index.json)")
    ap.add_argument("--method", action="append", default=[], help="method spec (repeatable)")
    ap.add_argument("--limit", type=int, default=0, help="only the first N samples")
    ap.add_argument("--thickness", type=float, default=1.0, help="pixel-height tracer thickness [px]")
    ap.add_argument("--out", default=None, help="output folder (default <data>/eval)")
    ap.add_argument("--no-failure", action="store_true", help="skip the failure charts")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument("--no-baselines", action="store_true",
                    help="only the --method specs (to add a method to an earlier evaluation: its "
                         "per_sample.csv rows have the same columns and can be concatenated)")
    a = ap.parse_args(argv)
    if a.no_baselines and not a.method:
        ap.error("--no-baselines needs at least one --method")
    specs = list(a.method) if a.no_baselines else list(BASELINES) + [m for m in a.method if m not in BASELINES]
    for m in specs:
        Method(m, a.thickness)                       # fail on a bad spec before any work
    out = a.out or os.path.join(a.data, "eval")
    os.makedirs(out, exist_ok=True)
    rows = evaluate(a.data, specs, a.limit, a.thickness, progress=not a.no_progress)
    summary = summarize(rows, specs)
    n = len({r["index"] for r in rows})
    res = load_sample(sample_files(a.data)[0])["shadow"].shape[0]
    title = f"{os.path.normpath(a.data)}: {n} samples, {res} px, thickness {a.thickness:g} px"
    md = (markdown_table(summary, title) + "\n`renderer_hard` is read from the file (0 ms); its ray-casting "
          "cost is part of generation.\n\n" + background_table(rows, specs))
    print(md)
    with open(os.path.join(out, "table.md"), "w") as fh:
        fh.write(md)
    write_csv(os.path.join(out, "table.csv"), summary)
    write_csv(os.path.join(out, "per_sample.csv"), rows)
    speed_accuracy_chart(summary, os.path.join(out, "speed_accuracy.png"), title)
    if not a.no_failure:
        from .failure import failure_charts
        for line in failure_charts(rows, out):
            print(line)
    print(f"wrote {out}/table.md, table.csv, per_sample.csv, speed_accuracy.png")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
