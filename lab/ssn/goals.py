"""Issue 14's goals for SSN++, read from ``pixgraph_lab.evaluate``'s per-sample rows.

    python -m pixgraph_lab.ssn.goals --wall data/wall_test2/eval/per_sample.csv \
        --ground data/ground_test2/eval/per_sample.csv --method pixgraph_lab.ssn.methods:node

Prints (Markdown) for each benchmark: mean RMSE / SSIM of the method against the
classical ``soft:256`` (goal: RMSE <= 0.75x, SSIM >=), mean RMSE per light-softness
bin against ``soft:64`` (goal: lower in every bin), on thin open objects
(``objects.THIN_TRAIN + THIN_TEST``; goal: at most 10% worse than ``soft:64``) and,
on the ground, against the renderer's own hard shadow (goal: better). Softness
here is the generator's ``relative_radius`` (light radius / distance to the
object's 3D centre). Every row gives the numbers, the ratio and whether the goal
holds; nothing is hidden when it does not.
"""
from __future__ import annotations

import argparse
import csv

import numpy as np

from pixgraph_lab.datagen.objects import THIN_TEST, THIN_TRAIN

BINS = (0.0, 0.05, 0.1, 0.2, 0.3, 1.0)


def read_rows(path: str) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _mean(rows, method, key, pick=lambda r: True) -> tuple[float, int]:
    v = [float(r[key]) for r in rows if r["method"] == method and pick(r)]
    return (float(np.mean(v)) if v else float("nan")), len(v)


def goal_rows(rows: list[dict], method: str, ground: bool) -> list[tuple]:
    """(goal, method value, baseline value, ratio, n, holds) rows of one benchmark."""
    out = []
    m, n = _mean(rows, method, "rmse")
    b, _ = _mean(rows, "soft:256", "rmse")
    out.append(("RMSE <= 0.75 x soft:256", m, b, m / b, n, m <= 0.75 * b))
    m, _ = _mean(rows, method, "ssim")
    b, _ = _mean(rows, "soft:256", "ssim")
    out.append(("SSIM >= soft:256", m, b, m / b, n, m >= b))
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        def pick(r, lo=lo, hi=hi):
            return lo <= float(r["relative_radius"]) < hi
        m, n = _mean(rows, method, "rmse", pick)
        if n == 0:
            continue
        b, _ = _mean(rows, "soft:64", "rmse", pick)
        out.append((f"RMSE < soft:64, softness {lo:g}-{hi:g}", m, b, m / b, n, m < b))
    thin = set(THIN_TRAIN + THIN_TEST)
    m, n = _mean(rows, method, "rmse", lambda r: r["object"] in thin)
    if n:
        b, _ = _mean(rows, "soft:64", "rmse", lambda r: r["object"] in thin)
        out.append(("thin open objects: RMSE <= 1.1 x soft:64", m, b, m / b, n, m <= 1.1 * b))
    if ground:
        m, n = _mean(rows, method, "rmse")
        b, _ = _mean(rows, "renderer_hard", "rmse")
        out.append(("RMSE < renderer's hard shadow", m, b, m / b, n, m < b))
    return out


def markdown(rows: list[dict], method: str, title: str, ground: bool) -> str:
    lines = [f"**{title}** ({method})", "", "| goal | SSN++ | baseline | ratio | n | met |", "|---|---|---|---|---|---|"]
    for g, m, b, r, n, ok in goal_rows(rows, method, ground):
        lines.append(f"| {g} | {m:.4f} | {b:.4f} | {r:.3f} | {n} | {'yes' if ok else '**no**'} |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--wall", help="per_sample.csv of the wall benchmark")
    ap.add_argument("--ground", help="per_sample.csv of the ground benchmark")
    ap.add_argument("--method", action="append", required=True, help="method spec as evaluated (repeatable)")
    a = ap.parse_args(argv)
    for path, ground in ((a.wall, False), (a.ground, True)):
        if not path:
            continue
        rows = read_rows(path)
        for m in a.method:
            print(markdown(rows, m, "ground" if ground else "wall", ground))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
