"""Preview stand-ins for the soft shadows, against the final soft shadow (not a test).

    python benchmarks/preview_shadow_bench.py [--runs 7] [--quick] [--blur-alone N]

While a handle or slider moves, the page shows previews: the graph at a working
resolution with every soft-shadow node swapped for its ``preview`` stand-in
(docs/server.md). This compares the candidate stand-ins with what the user
sees on release, ``pixgraph.SoftShadow`` with 64 light samples, computed at the
same working resolution:

  hard      pixgraph.HardShadow: the hard shadow of the light's centre (the
            stand-in before PreviewShadow);
  soft2/4/8 SoftShadow's own math with 2, 4 or 8 light samples;
  pcss      pixgraph.PreviewShadow: the hard shadow widened by the penumbra
            estimate softness x blocker distance (ops/preview_shadow.py);
  pcss_aniso the same with the background's penumbra stretched along its long
            axis (``penumbra_blur``'s geometry: the light's disk extremes
            through the blocker onto the receiver's tangent plane), the
            candidate of issue 24's note (docs/server.md has the rule it met or
            missed); its boxes summed by the OpenCL kernel ``swept_boxes``.

Accuracy, over the example graphs with a soft shadow (graphs/wall_corner_shadow,
ground_shadow, steps_shadow, auto_shadow at the page's working resolution 0.5:
256 x 256; graphs/own_photo at 0.5: 320 x 240), each with the cutout height
``contact_line`` and ``learned``, the light's radius x 0.5, 1 and 2 and its
azimuth as in the graph and turned by 40 degrees: the RMSE of the darkness
and the IoU of the shadow (darkness > 0.3) against the final, mean and worst
over the scenes.

Cost, at about 0.5 MP (the page's drag budget, ``PREVIEW_PIXELS`` in
render.js): graphs/own_photo's photo enlarged to 816 x 612 (what a 20 MP photo
is previewed at) with the placement scaled to it, the light as in the graph,
both cutout heights: the median wall time of ``--runs`` calls of each
stand-in's computation (what its node's compute does after the input checks, on
a scene uploaded once: the host preparation and upload, the same for every
stand-in, are not counted), with the CPU time the process used meanwhile, and
``+hard``: the median extra over the hard shadow measured in the same loop.
The machine is shared: the load average is printed before and after.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import platform
import statistics
import sys
import time
import warnings

import numpy as np

from _machine import cpu_model
from pixgraph.session import Session
from pixgraph_nodes.ops import preview_shadow as P
from pixgraph_nodes.ops import shadow as S
from pixgraph_nodes.ops.lights import disk_extremes, disk_samples, light_point
from pixgraph_nodes.ops.softness import softness_of

ROOT = pathlib.Path(__file__).resolve().parent.parent
GRAPHS = ("wall_corner_shadow", "ground_shadow", "steps_shadow", "auto_shadow", "own_photo")
INPUTS = ("mask", "fg_height", "bg_height", "light", "camera")
WORK = 0.5
CANDIDATES = ("hard", "soft2", "soft4", "soft8", "pcss", "pcss_aniso")


def load(session, path):
    """The graph with its cutout height's colour input connected (method learned reads it)."""
    from pixgraph.graph import GraphBuilder
    g = session.load(path)
    if "image" not in g.nodes["fg_h"].inputs:
        b = GraphBuilder.from_graph(g, session.registry)
        b.connect("cutout.image", "fg_h.image")
        g = b.build()
    return g


def shadow_refs(session, g):
    """The refs of the graph's ``shadow`` node's inputs, its thickness [px, full size]
    and its light's params."""
    inst = g.nodes["shadow"]
    refs = [f"{inst.inputs[k].node}.{inst.inputs[k].output}" for k in INPUTS]
    return refs, float(inst.params.get("thickness", 1.0)), dict(g.nodes["light"].params)


def candidate(name, device, scene, mask, fg, light, cam):
    """The darkness of stand-in ``name`` on an uploaded scene (what its node computes)."""
    if name == "hard":
        return 1.0 - scene.hard_shadow(light_point(light, cam))
    if name.startswith("soft"):
        n = int(name[4:])
        return 1.0 - scene.soft_shadow(disk_samples(light, cam, n, 0) if light.is_area else light_point(light, cam)[None])
    if name in ("pcss", "pcss_aniso"):
        soft = softness_of(light, cam, mask, fg) if light.is_area else 0.0
        lp = light_point(light, cam)
        dark, dist = scene.hard_shadow_distance(lp)
        geometry = None
        if name == "pcss_aniso":
            geometry = (scene.prep.bg, lp, disk_extremes(light, cam))
        # the device sums the stretched boxes (kernel swept_boxes), as the node's compute does
        return P.penumbra_blur(dark, dist, np.asarray(mask) > 0.5, soft, geometry, device=device)
    raise ValueError(name)


def final(scene, light, cam):
    return 1.0 - scene.soft_shadow(disk_samples(light, cam, 64, 0) if light.is_area else light_point(light, cam)[None])


def scores(d, ref):
    rmse = float(np.sqrt(np.mean((d - ref) ** 2)))
    a, b = d > 0.3, ref > 0.3
    union = int((a | b).sum())
    return rmse, (float((a & b).sum()) / union if union else 1.0)


def accuracy(session, quick):
    rows = []
    graphs = GRAPHS[:2] if quick else GRAPHS
    for name in graphs:
        path = load(session, str(ROOT / "graphs" / f"{name}.yaml"))
        refs, thickness, lp = shadow_refs(session, path)
        for method in ("contact_line", "learned"):
            for rf in ((1.0,) if quick else (0.5, 1.0, 2.0)):
                for turn in ((0.0,) if quick else (0.0, 40.0)):
                    params = {"fg_h.method": method, "light.radius": lp.get("radius", 0.3) * rf,
                              "light.azimuth": lp.get("azimuth", 20.0) + turn}
                    r = session.run(path, outputs=refs, params=params, scale=WORK)
                    mask, fg, bg, light, cam = (r[x] for x in refs)
                    scene = P.PreviewScene(session.device, mask, fg, bg, thickness * WORK)
                    ref = final(scene, light, cam)
                    row = {"graph": name, "height": method, "radius": rf, "turn": turn, "shape": mask.shape}
                    for c in CANDIDATES:
                        row[c] = scores(candidate(c, session.device, scene, mask, fg, light, cam), ref)
                    rows.append(row)
                    print(f"  {name:20s} {method:12s} radius x{rf:<4g} az +{turn:<3g} {mask.shape[1]}x{mask.shape[0]}  "
                          + "  ".join(f"{c} {row[c][0]:.4f}/{row[c][1]:.3f}" for c in CANDIDATES), flush=True)
    return rows


def photo_scene(session, method):
    """graphs/own_photo at 816 x 612: its photo enlarged, placement and junction scaled."""
    from PIL import Image
    path = load(session, str(ROOT / "graphs" / "own_photo.yaml"))
    refs, thickness, _ = shadow_refs(session, path)
    photo = Image.open(ROOT / "graphs" / "assets" / "own_photo.jpg").convert("RGB")
    k = 816 / photo.width
    big = np.asarray(photo.resize((816, 612), Image.BICUBIC), np.float32) / 255.0
    params = {"place.foot": [270 * k, 345 * k], "place.scale": 0.8 * k,
              "bg_h.junction_points": [0, 262 * k, 816, 292 * k], "fg_h.method": method}
    r = session.run(path, outputs=refs, params=params, bind={"photo": big})
    return [r[x] for x in refs], thickness * k


def timing(session, runs, quick):
    out = []
    for method in (("contact_line",) if quick else ("contact_line", "learned")):
        (mask, fg, bg, light, cam), thickness = photo_scene(session, method)
        scene = P.PreviewScene(session.device, mask, fg, bg, thickness)
        ref = final(scene, light, cam)
        for c in CANDIDATES:        # warm-up (kernel builds)
            candidate(c, session.device, scene, mask, fg, light, cam)
        wall = {c: [] for c in CANDIDATES}
        cpu = {c: [] for c in CANDIDATES}
        for _ in range(runs):
            for c in CANDIDATES:
                c0, t0 = time.process_time(), time.perf_counter()
                candidate(c, session.device, scene, mask, fg, light, cam)
                wall[c].append(time.perf_counter() - t0)
                cpu[c].append(time.process_time() - c0)
        for c in CANDIDATES:
            extra = statistics.median(w - h for w, h in zip(wall[c], wall["hard"]))
            rmse, iou = scores(candidate(c, session.device, scene, mask, fg, light, cam), ref)
            out.append((method, c, mask.shape, statistics.median(wall[c]), statistics.median(cpu[c]), extra, rmse, iou))
            print(f"  own_photo 816x612 {method:12s} {c:6s} wall {1e3 * out[-1][3]:7.1f} ms  cpu {1e3 * out[-1][4]:7.1f} ms"
                  f"  +hard {1e3 * extra:6.1f} ms  rmse {rmse:.4f} iou {iou:.3f}", flush=True)
    return out


def blur_alone(session, reps):
    """The penumbra estimate alone (``penumbra_blur``): the square box, the stretched one
    with its boxes summed by the kernel (``pcss_aniso``, what the node runs) and by the
    numpy reference (``numpy``), alternated ``reps`` times on the 816 x 612 scenes' traced
    hard shadow: wall medians and the medians of the paired differences from the square."""
    for method in ("contact_line", "learned"):
        (mask, fg, bg, light, cam), thickness = photo_scene(session, method)
        scene = P.PreviewScene(session.device, mask, fg, bg, thickness)
        soft = softness_of(light, cam, mask, fg) if light.is_area else 0.0
        lp = light_point(light, cam)
        dark, dist = scene.hard_shadow_distance(lp)
        inside = np.asarray(mask) > 0.5
        geometry = (scene.prep.bg, lp, disk_extremes(light, cam))
        runs = (("pcss", None, None), ("pcss_aniso", geometry, session.device), ("numpy", geometry, None))
        t = {c: [] for c, _, _ in runs}
        for _ in range(reps):
            for c, g, dev in runs:
                t0 = time.perf_counter()
                P.penumbra_blur(dark, dist, inside, soft, g, device=dev)
                t[c].append(time.perf_counter() - t0)
        extra = {c: statistics.median(a - b for a, b in zip(t[c], t["pcss"])) for c in t}
        print(f"  own_photo 816x612 {method:12s} penumbra_blur alone: pcss {1e3 * statistics.median(t['pcss']):.1f} ms"
              + "".join(f"  {c} {1e3 * statistics.median(t[c]):.1f} ms (+{1e3 * extra[c]:.1f})"
                        for c in ("pcss_aniso", "numpy")), flush=True)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=7, help="timed calls per stand-in and scene")
    ap.add_argument("--quick", action="store_true", help="two graphs, one light, one height: a smoke run")
    ap.add_argument("--blur-alone", type=int, default=0, metavar="N",
                    help="only time penumbra_blur alone, square against stretched (kernel and numpy), "
                         "alternated N times")
    args = ap.parse_args(argv)
    warnings.simplefilter("ignore")
    session = Session()
    print(f"machine: {cpu_model()}; {platform.python_version()}; device {session.device.name}")
    print(f"load average before: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    if args.blur_alone:
        blur_alone(session, args.blur_alone)
        print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
        return 0
    print(f"accuracy against SoftShadow (64 samples) at work {WORK} (rmse/IoU of darkness > 0.3):")
    rows = accuracy(session, args.quick)
    print(f"\nsummary over {len(rows)} scenes:   RMSE mean / max      IoU mean / min")
    for c in CANDIDATES:
        r = np.array([row[c][0] for row in rows])
        i = np.array([row[c][1] for row in rows])
        print(f"  {c:6s}  {r.mean():.4f} / {r.max():.4f}     {i.mean():.3f} / {i.min():.3f}")
    for method in ("contact_line", "learned"):
        sub = [row for row in rows if row["height"] == method]
        if sub:
            print(f"  {method}: " + "  ".join(
                f"{c} {np.mean([row[c][0] for row in sub]):.4f}/{np.mean([row[c][1] for row in sub]):.3f}"
                for c in CANDIDATES))
    print(f"\ncost at about 0.5 MP (median of {args.runs} calls each):")
    timing(session, args.runs, args.quick)
    print(f"load average after: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    sys.exit(main())
