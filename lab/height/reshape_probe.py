"""Exploratory oracle probe (issue 24, fourteenth session; no rule judged, nothing shipped):
could ONE more continuous handle that reshapes the pixel-height map between the heights
the edit's handles set remove more of the soft shadow's error than user B's best plan?

For each case of ``benchmarks/page_height_fix.py --explore 23,21,5,17,20,6,2,0,3,1
--users A,B`` (sample x height method), user B's best plan's edited map (the plan
recorded in docs/height-record.md, "Measured: a user who watches the shadow", its
params found again with ``plan_params`` and user B's ``watch`` exactly as the
script's ``choose_plan`` does; ``--full`` runs ``choose_plan`` itself over all
``PLANS``) is reshaped by each candidate below and bound in place of the
``PixelHeightEdit`` node's output (``Session.run(bind=...)``): the shadow is the
same graph's (PlaceCutout -> SoftShadow, 48 samples, 512^2) and its RMSE vs the
true heights' shadow is the script's (``measure``: outside the cutout). The best
value of each family over its parameter (an oracle: it sees the truth):

* profile: ``h' = T (h / T) ** g`` inside the mask (``T`` the map's max over the
  mask; heights <= 0 kept), g in ``GAMMAS``;
* blend: ``h' = (1 - w) h + w h_other``, ``h_other`` the other height method's map
  edited with the same params, w in ``WEIGHTS``;
* scale: ``h' = s h`` (about the ground, height 0), s in ``SCALES``.

Heights in pixels of the cutout's map (256^2; the graph places it at scale 2).

    OMP_NUM_THREADS=1 PIXGRAPH_THREADS=1 python -m pixgraph_lab.height.reshape_probe \\
        --shadows data/hreal/wall_named64 [--cases 23:contact_line,...] [--full] [--out runs/x.jsonl]
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

from pixgraph_lab.height.edit_plans import OTHER, PLANS, plan_method, plan_params

GAMMAS = (0.5, 0.6, 0.7, 0.8, 0.9, 1.1, 1.25, 1.5, 1.75, 2.0)
WEIGHTS = (0.25, 0.5, 0.75)
SCALES = (0.7, 0.8, 0.9, 1.1, 1.2, 1.3)
#: ``--fine``: the same families on finer grids near the plan as it is (g = w = 0, s = 1)
FINE = {"profile": (0.92, 0.94, 0.96, 0.98, 1.02, 1.04, 1.06, 1.08, 1.15), "blend": (0.05, 0.1, 0.15, 0.2),
        "scale": (0.94, 0.96, 0.98, 1.02, 1.04, 1.06)}

#: user B's best plan per case (docs/height-record.md, "Measured: a user who watches the shadow")
B_PLAN = {
    (23, "contact_line"): "other method + 1 contact + top", (23, "learned"): "1 contact + top",
    (21, "contact_line"): "other method + depth + top", (21, "learned"): "depth + top",
    (5, "contact_line"): "lying + thickness", (5, "learned"): "lying + thickness",
    (17, "contact_line"): "other method + depth", (17, "learned"): "depth",
    (20, "contact_line"): "other method + depth", (20, "learned"): "depth",
    (6, "contact_line"): "lying + thickness", (6, "learned"): "lying + thickness",
    (2, "contact_line"): "other method", (2, "learned"): "3 contacts",
    (0, "contact_line"): "lying + thickness", (0, "learned"): "lying + thickness",
    (3, "contact_line"): "other method + depth", (3, "learned"): "depth",
    (1, "contact_line"): "other method + depth", (1, "learned"): "depth",
}
#: user B removed < 50 % there: done first
FIRST = ((23, "contact_line"), (17, "contact_line"), (20, "contact_line"), (20, "learned"), (6, "learned"),
         (2, "learned"), (3, "contact_line"), (3, "learned"))


def profile(h: np.ndarray, mask: np.ndarray, g: float) -> np.ndarray:
    """``T (h / T) ** g`` on the mask's pixels with h > 0 (T: max of h over the mask) [px]."""
    t = float(h[mask].max()) if mask.any() else 0.0
    if t <= 0:
        return h.copy()
    on = mask & (h > 0)
    out = h.copy()
    out[on] = t * (h[on] / t) ** g
    return out


def _fix():
    """The benchmark script as a module (benchmarks/ is not a package)."""
    here = os.path.dirname(os.path.abspath(__file__))
    bench = os.path.join(os.path.dirname(os.path.dirname(here)), "benchmarks")
    if bench not in sys.path:
        sys.path.insert(0, bench)
    import page_height_fix
    return page_height_fix


def b_plan(fix, sc: dict, method: str, name: str) -> tuple[dict, float]:
    """User B's params for plan ``name`` (``choose_plan``'s loop body for that plan) and its RMSE."""
    plan = PLANS[name]
    meth = plan_method(plan, method)

    def edited(p):
        return fix.edited_map(sc["graph"], p, meth)

    def watch(cands):
        return int(np.argmin([fix.measure(sc["graph"], c, meth)["rmse"] for c in cands]))
    p = plan_params(plan, sc["known_h"], sc["mask"], edited, watch=watch, targets={})
    return p, fix.measure(sc["graph"], p, meth)["rmse"]


def rmse_bound(fix, sc: dict, h: np.ndarray) -> float:
    """``measure``'s RMSE with the edit's output replaced by ``h``."""
    ses = fix._session()
    truth, alpha = fix._TRUTH[sc["graph"]]
    got = ses.run(ses.load(sc["graph"]), outputs=["shadow.darkness"],
                  bind={"edit": np.ascontiguousarray(h, dtype=np.float32)})["shadow.darkness"]
    keep = alpha < 0.02
    return float(np.sqrt(np.mean((got[keep] - truth[keep]) ** 2)))


#: ``--joint``: the reshapes whose plan is watched again with the reshape on (user B's drags re-chosen)
JOINT = {"profile": (0.8, 0.9, 1.1, 1.25), "blend": (0.25, 0.5)}


def joint_case(fix, sc: dict, idx: int, method: str) -> dict:
    """User B's plan (B_PLAN) done again with each JOINT reshape applied to the edited map
    while B watches: the drags' candidates (``plan_params``'s, from the unreshaped map) are
    the same, B keeps the one whose reshaped map's shadow comes closest."""
    t0 = time.time()
    before = fix.measure(sc["graph"], {}, method)["rmse"]
    name = B_PLAN[(idx, method)]
    params, after = b_plan(fix, sc, method, name)
    plan = PLANS[name]
    meth = plan_method(plan, method)
    mask = sc["mask"]

    def edited(p, m=meth):
        return np.asarray(fix.edited_map(sc["graph"], p, m), dtype=np.float32)
    fam = {"profile": {}, "blend": {}}
    for f, values in JOINT.items():
        for v in values:
            def reshape(p, f=f, v=v):
                h = edited(p)
                return profile(h, mask, v) if f == "profile" else (1 - v) * h + v * edited(p, OTHER[meth])

            def watch(cands, reshape=reshape):
                return int(np.argmin([rmse_bound(fix, sc, reshape(c)) for c in cands]))
            p = plan_params(plan, sc["known_h"], mask, edited, watch=watch, targets={})
            fam[f][v] = (rmse_bound(fix, sc, reshape(p)), p)
    return {"idx": idx, "object": sc["object"].removeprefix("named:"), "method": method, "plan": name,
            "params": params, "before": before, "after": after, "joint": True,
            "families": {k: {str(p): v[0] for p, v in d.items()} for k, d in fam.items()},
            "joint_params": {k: {str(p): v[1] for p, v in d.items()} for k, d in fam.items()},
            "seconds": time.time() - t0, "load": os.getloadavg()[0]}


def probe_case(fix, sc: dict, idx: int, method: str, full: bool, grids: dict | None = None) -> dict:
    """One case's numbers (``grids``: each family's parameters, default GAMMAS, WEIGHTS, SCALES)."""
    grids = grids or {"profile": GAMMAS, "blend": WEIGHTS, "scale": SCALES}
    t0 = time.time()
    before = fix.measure(sc["graph"], {}, method)["rmse"]
    if full:
        name, params, every = fix.choose_plan(sc, method, "B")
        after = every[name][1]["rmse"]
    else:
        name = B_PLAN[(idx, method)]
        params, after = b_plan(fix, sc, method, name)
    meth = plan_method(PLANS.get(name, []), method)

    def edited(m):
        return np.asarray(fix.edited_map(sc["graph"], params, m), dtype=np.float32)
    h = edited(meth)
    mask = sc["mask"]
    check = rmse_bound(fix, sc, h)          # the bound map's shadow is the plan's own
    fam = {"profile": {}, "blend": {}, "scale": {}}
    for gm in grids["profile"]:
        fam["profile"][gm] = rmse_bound(fix, sc, profile(h, mask, gm))
    h_other = edited(OTHER[meth])
    for w in grids["blend"]:
        fam["blend"][w] = rmse_bound(fix, sc, (1 - w) * h + w * h_other)
    for s in grids["scale"]:
        fam["scale"][s] = rmse_bound(fix, sc, s * h)
    return {"idx": idx, "object": sc["object"].removeprefix("named:"), "method": method, "plan": name,
            "params": params, "before": before, "after": after, "bound_check": check,
            "families": {k: {str(p): v for p, v in d.items()} for k, d in fam.items()},
            "seconds": time.time() - t0, "load": os.getloadavg()[0]}


def removed(before: float, x: float) -> float:
    """The script's share removed: 1 - after / before (0 when there was no error)."""
    return 1 - x / before if before > 0 else 0.0


def table(rows: list) -> str:
    fams = [f for f in ("profile", "blend", "scale") if all(f in r["families"] for r in rows)]
    sym = {"profile": "g", "blend": "w", "scale": "s"}
    out = ["| case | plan (user B) | RMSE before | user B after (removed) | "
           + " | ".join(f"{f}: best {sym[f]}, RMSE (removed)" for f in fams) + " |", "|---" * (4 + len(fams)) + "|"]
    counts = {"B": [], **{f: [] for f in fams}}
    for r in rows:
        b, a = r["before"], r["after"]
        cells = []
        counts["B"].append(removed(b, a))
        for f in fams:
            p, v = min(r["families"][f].items(), key=lambda kv: kv[1])
            best = min(v, a)                 # the oracle may keep the plan as it is
            counts[f].append(removed(b, best))
            cells.append(f"{p}, {v:.3f} ({removed(b, v):.0%})")
        out.append(f"| {r['idx']} {r['object']} {r['method'].replace('_', ' ')} | {r['plan']} | {b:.3f} | "
                   f"{a:.3f} ({removed(b, a):.0%}) | " + " | ".join(cells) + " |")
    out.append("")
    for k, v in counts.items():
        v = np.array(v)
        label = "user B alone" if k == "B" else f"user B + {k} (oracle best, or the plan as is)"
        out.append(f"{label}: >= 50 % removed in {int((v >= 0.5).sum())} of {len(v)}, median {np.median(v):.0%} "
                   f"(min {v.min():.0%}, max {v.max():.0%})")
    return "\n".join(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shadows", default="data/hreal/wall_named64")
    ap.add_argument("--cases", default=None, help="idx:method,... (default: FIRST, then the other 12)")
    ap.add_argument("--full", action="store_true", help="user B's best plan by choose_plan over all PLANS (slow)")
    ap.add_argument("--out", default="runs/reshape_probe.jsonl", help="one JSON line per case (appended); with --table, files to merge")
    ap.add_argument("--joint", action="store_true", help="JOINT's reshapes with user B's drags watched again")
    ap.add_argument("--fine", action="store_true", help="the families on FINE's grids instead")
    ap.add_argument("--table", action="store_true", help="only print the table of --out's cases")
    a = ap.parse_args(argv)
    if a.table:     # --out may name several files (comma-separated): each case's families merged
        rows = {}
        for path in a.out.split(","):
            with open(path) as f:
                for r in (json.loads(x) for x in f if x.strip()):
                    key = (r["idx"], r["method"])
                    if key in rows:
                        for k, d in r["families"].items():
                            rows[key]["families"][k].update(d)
                    else:
                        rows[key] = r
        print(table(list(rows.values())))
        return 0
    fix = _fix()
    cases = ([(int(c.split(":")[0]), c.split(":")[1]) for c in a.cases.split(",")] if a.cases
             else list(FIRST) + [k for k in B_PLAN if k not in FIRST])
    print(f"machine: {fix.cpu_model()}; load average {os.getloadavg()[0]:.2f}; "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')} PIXGRAPH_THREADS={os.environ.get('PIXGRAPH_THREADS')}",
          flush=True)
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    rows = []
    for idx, method in cases:
        with tempfile.TemporaryDirectory(prefix="pixgraph-reshape-") as d:
            sc = fix.build_scene(os.path.join(a.shadows, f"{idx:05d}.npz"), d)
            r = (joint_case(fix, sc, idx, method) if a.joint
                 else probe_case(fix, sc, idx, method, a.full, FINE if a.fine else None))
        rows.append(r)
        with open(a.out, "a") as f:
            f.write(json.dumps(r) + "\n")
        fams = "; ".join(f"{k} " + ", ".join(f"{p}:{v:.4f}" for p, v in d.items()) for k, d in r["families"].items())
        print(f"{idx} {r['object']} {method}: plan {r['plan']} {r['params']}; before {r['before']:.4f} after "
              f"{r['after']:.4f} (bound {r.get('bound_check', float('nan')):.4f}); {fams}; {r['seconds']:.0f} s, load "
              f"{r['load']:.2f}", flush=True)
    print(table(rows))
    print(f"load average at the end {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
