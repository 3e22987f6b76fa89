"""What is left of a wrong pixel height after the page benchmark's best plan
(benchmarks/page_height_fix.py): where the edited height still differs from the true
one, and how much of the shadow's error each kind of difference carries.

    python benchmarks/page_height_residual.py --shadows data/hreal/wall_named64 \\
        --samples 23,21,5,17,20,6,2,0,3,1

For each sample and height method it takes the best plan of at most 3 page actions
(``page_height_fix.choose_plan``: the simulated user, the same scene and graph), the
edited map ``e`` and the heights the user knows ``t`` (``known_heights``) over the
cutout, and prints, for the residual ``r = t - e`` [px]:

* its mean absolute value and mean (bias);
* the share of its variance carried by its column means (an offset per column: a
  part whose ground is elsewhere) and by its row means (a profile up the object);
* the share of what is left inside the rows (``r`` minus its row means) carried by a
  bulge across each row: ``sqrt(1 - t^2) w(v)`` with ``t`` the pixel's offset from
  the row's middle over the row's half-width ``w(v)``, its row mean removed (a
  rounded body's height growing toward the middle of each row), with the fitted
  slope ``beta`` (> 0: the edit needs more bulge);
* the mean of ``r`` in the row's middle third, the next third and the outer third
  (by ``|t|``), and in the bottom, middle and top third of the object's rows;

and the shadow's RMSE against the true heights' shadow (the benchmark's measure) with
the map ``e``, with ``e`` corrected exactly by the residual's row means, by its column
means, and scaled by the least-squares factor ``k`` (t ~ k e): how much of the shadow's
error each kind of difference carries (the true map itself gives the floor, the known
heights' small outline differences).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import page_height_fix as P  # noqa: E402
from _machine import cpu_model  # noqa: E402


def shadow_of_map(sc: dict, hmap: np.ndarray, tag: str) -> np.ndarray:
    """The shadow of the scene's graph with the cutout's height read from ``hmap`` [px]
    (no edit), clipped at 0 as the shadow node requires."""
    import yaml
    d = os.path.dirname(sc["graph"])
    np.save(os.path.join(d, f"h_{tag}.npy"), np.maximum(np.asarray(hmap, np.float32), 0))
    with open(sc["graph"]) as f:
        doc = yaml.safe_load(f)
    doc["nodes"]["fg_h"] = {"type": "pixgraph.LoadPixelHeight", "params": {"path": f"h_{tag}.npy"}}
    path = os.path.join(d, f"g_{tag}.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    ses = P._session()
    return ses.run(ses.load(path), outputs=["shadow.darkness"])["shadow.darkness"]


def residual_stats(e: np.ndarray, t: np.ndarray, m: np.ndarray) -> dict:
    """The residual's numbers (module doc) of the edited map ``e`` [px] against ``t`` [px]
    over the mask ``m`` (all (H, W)): ``mae``, ``bias`` [px]; the variance shares ``cols``,
    ``rows`` and ``bulge`` (of what is left within the rows) in [0, 1], with ``beta`` (the
    bulge's slope, no unit); ``across`` and ``up``, the residual's means by thirds [px];
    the maps ``row_fix`` and ``col_fix`` [px] (``e`` corrected by the residual's row or
    column means) and the least-squares factor ``k`` (t ~ k e)."""
    H, W = m.shape
    r = np.where(m, t - e, 0.0)
    rv = r[m]
    rows = np.array([r[i][m[i]].mean() if m[i].any() else 0.0 for i in range(H)])
    cols = np.array([r[:, j][m[:, j]].mean() if m[:, j].any() else 0.0 for j in range(W)])
    var = max(float(rv.var()), 1e-12)
    c, w = np.zeros(H), np.zeros(H)
    for i in range(H):
        xs = np.flatnonzero(m[i])
        if len(xs):
            c[i], w[i] = (xs[0] + xs[-1] + 1) / 2, (xs[-1] + 1 - xs[0]) / 2
    u = np.arange(W)[None, :] + 0.5
    tt = np.where(w[:, None] > 0, np.abs(u - c[:, None]) / np.maximum(w[:, None], 1e-9), 0.0)
    prof = np.sqrt(np.clip(1 - tt ** 2, 0, 1)) * w[:, None]
    pm = np.array([prof[i][m[i]].mean() if m[i].any() else 0.0 for i in range(H)])
    profc, within = prof - pm[:, None], r - rows[:, None]
    beta = float((within[m] * profc[m]).sum() / max((profc[m] ** 2).sum(), 1e-9))
    bulge = 1 - (within - beta * profc)[m].var() / max(float(within[m].var()), 1e-12)
    ys = np.nonzero(m)[0]
    frac = np.broadcast_to(((ys.max() - np.arange(H)) / max(ys.max() - ys.min(), 1))[:, None], m.shape)

    def mean(sel):
        return float(r[m & sel].mean()) if (m & sel).any() else float("nan")
    return {"mae": float(np.abs(rv).mean()), "bias": float(rv.mean()),
            "cols": 1 - float((r - cols[None, :])[m].var()) / var, "rows": 1 - float((r - rows[:, None])[m].var()) / var,
            "bulge": float(bulge), "beta": beta,
            "across": [mean(tt < 1 / 3), mean((tt >= 1 / 3) & (tt < 2 / 3)), mean(tt >= 2 / 3)],
            "up": [mean(frac < 1 / 3), mean((frac >= 1 / 3) & (frac < 2 / 3)), mean(frac >= 2 / 3)],
            "row_fix": np.where(m, e + rows[:, None], 0.0), "col_fix": np.where(m, e + cols[None, :], 0.0),
            "k": float((e[m] * t[m]).sum() / max(float((e[m] ** 2).sum()), 1e-9))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shadows", default=os.path.join(P.REPO, "data", "hreal", "wall_named64"))
    ap.add_argument("--samples", default="23,21,5,17,20,6,2,0,3,1")
    a = ap.parse_args(argv)
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}")
    print("| sample | height | best plan | shadow RMSE: before -> after | residual MAE, bias [px] | variance in column "
          "/ row means | bulge share of within-row (beta) | mean residual across the row: middle / next / outer "
          "third [px] | up the object: bottom / middle / top third [px] | shadow RMSE with exact row fix / column fix "
          "/ best scale k / true map |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for idx in (int(x) for x in a.samples.split(",")):
        with tempfile.TemporaryDirectory(prefix="pixgraph-hres-") as d:
            sc = P.build_scene(os.path.join(a.shadows, f"{idx:05d}.npz"), d)
            truth, alpha = P.shadow_rmse(sc["graph"], {}, "true")
            keep = alpha < 0.02
            ses = P._session()
            g = ses.load(sc["graph"])
            m, t = sc["mask"], np.asarray(sc["known_h"], np.float64)

            def rmse(x):
                return float(np.sqrt(np.mean((x[keep] - truth[keep]) ** 2)))
            for method in ("contact_line", "learned"):
                best, params, every = P.choose_plan(sc, method)
                q = {f"edit.{k}": v for k, v in params.items()}
                q["fg_h.method"] = P.plan_method(P.PLANS.get(best, []), method)
                e = np.asarray(ses.run(g, outputs=["edit.height"], params=q)["edit.height"], np.float64)
                s = residual_stats(e, t, m)
                fixes = [rmse(shadow_of_map(sc, s["row_fix"], "rows")), rmse(shadow_of_map(sc, s["col_fix"], "cols")),
                         rmse(shadow_of_map(sc, np.where(m, s["k"] * e, 0.0), "scale")),
                         rmse(shadow_of_map(sc, t, "true"))]
                print(f"| {idx} {sc['object'].removeprefix('named:')} | {method.replace('_', ' ')} | {best} | "
                      f"{every['none'][1]['rmse']:.3f} -> {every[best][1]['rmse']:.3f} | {s['mae']:.1f}, {s['bias']:+.1f} | "
                      f"{s['cols']:.2f} / {s['rows']:.2f} | {s['bulge']:.2f} ({s['beta']:+.2f}) | "
                      + " / ".join(f"{x:+.1f}" for x in s["across"]) + " | " + " / ".join(f"{x:+.1f}" for x in s["up"])
                      + f" | {fixes[0]:.3f} / {fixes[1]:.3f} / {fixes[2]:.3f} (k {s['k']:.3f}) / {fixes[3]:.3f} |",
                      flush=True)
    print(f"load average {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
