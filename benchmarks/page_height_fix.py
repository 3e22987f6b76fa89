"""Fixing a wrong pixel height by hand in the page, on the repo's own real-photo check
examples (docs/height.md, "The real-photo check": our Mitsuba renders of held-out
named meshes with exact pixel heights), in headless Chromium, in at most 3 drags.

    python benchmarks/page_height_fix.py --shadows data/hreal/wall_named64 \\
        [--samples 17,20,6] [--shots docs/img] [--steps 10]

(``data/hreal/wall_named64`` is made by ``python -m pixgraph_lab.height.shadow_test
--benchmark wall --n 80 --seed 0 --light-samples 64 --out data/hreal/wall_named64``;
the samples used here are among its first 25.)

For each sample a scene for the page is built from the sample alone, at twice its
size (512^2): the plate is a flat grey floor and wall from the sample's background
(``bg_is_ground``), the cutout its render and mask, the background height its own
(x2), the camera its own; the cutout is placed back where it was (scale 2). The
graph is the own-photo template's chain: ``CutoutHeight`` (``method: learned``) ->
``PixelHeightEdit`` -> ``PlaceCutout`` -> ``SoftShadow`` (48 samples) ->
``Composite``, with one light for all (azimuth -35, elevation 40 deg: the shadow
falls on the floor and the wall behind, as in the own-photo template).

The simulated user (rules fixed before any measurement; like real_photos.py's):
1. drags the hollow contact handle at the cutout's foot to the visible pixel whose
   true height is < 1 px lowest in the left third of those pixels' columns;
2. drags that point's... no: "+ contact" then presses at the lowest such pixel of
   the right third (a second foot: the ground line through both);
3. drags the tilt handle on the object's top so its height is the true one there
   (the user sees how far the shadow reaches and matches it).
Each is one pointer drag or press in the page; between them the page shows the
previews and the final. Then the saved graph's params are read back and the
shadow of the edited heights is compared with the shadow of the *true* heights
through the same graph (RMSE of the shadow darkness over the visible background,
in-process, full size), next to the learned and the contact-line heights'.

Writes ``page_height_before.png`` / ``page_height_after.png`` (the page's stage,
downscaled) for the first sample into --shots, and prints a table.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import cpu_model  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
S = 2   # the scene's size / the sample's


def _srgb8(x):
    x = np.clip(x, 0, 1)
    return (np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055) * 255 + 0.5).astype(np.uint8)


def build_scene(sample: str, dest: str) -> dict:
    """The page's scene of one benchmark sample in ``dest`` (module doc); returns facts."""
    from PIL import Image

    from pixgraph_nodes.ops.lights import foot_of_mask
    with np.load(sample) as z:
        meta = json.loads(str(z["meta"]))
        rgb, alpha, mask = z["rgb"].astype(np.float32), z["alpha"].astype(np.float32), z["mask"]
        true_h, bg_h, ground = z["fg_height"].astype(np.float32), z["bg_height"].astype(np.float32), z["bg_is_ground"]
    os.makedirs(dest, exist_ok=True)
    H, W = mask.shape
    # the plate: floor and wall in two greys, a little light falloff; the sample's size x S
    v = (np.arange(H * S) + 0.5)[:, None] / (H * S)
    g = np.repeat(np.repeat(ground, S, 0), S, 1)
    plate = np.where(g, 0.42 + 0.1 * v, 0.62 - 0.08 * v)[..., None] * np.array([1.0, 0.96, 0.9])
    Image.fromarray(_srgb8(plate)).save(os.path.join(dest, "plate.png"))
    cut = np.concatenate([_srgb8(np.where(alpha[..., None] > 0, rgb / np.maximum(alpha[..., None], 1e-6), 0)),
                          (np.clip(alpha, 0, 1) * 255 + 0.5).astype(np.uint8)[..., None]], axis=2)
    Image.fromarray(cut, "RGBA").save(os.path.join(dest, "cutout.png"))
    np.save(os.path.join(dest, "true_height.npy"), np.where(mask, true_h, 0).astype(np.float32))
    bg2 = np.repeat(np.repeat(bg_h, S, 0), S, 1) * S
    np.save(os.path.join(dest, "bg_height.npy"), bg2.astype(np.float32))
    cam = meta["scene"]["camera"]
    fu, fv = foot_of_mask(alpha)
    graph = {
        "pixgraph": 1,
        "nodes": {
            "cutout": {"type": "pixgraph.LoadImage", "params": {"path": "cutout.png"}},
            "photo": {"type": "pixgraph.LoadImage", "params": {"path": "plate.png"}},
            "cam": {"type": "pixgraph.Camera", "inputs": {"image": "photo.image"},
                    "params": {"hfov": round(cam["hfov"], 4), "horizon": round(cam["horizon"] * S, 2),
                               "cam_height": cam["cam_height"]}},
            "fg_h": {"type": "pixgraph.CutoutHeight", "inputs": {"mask": "cutout.alpha", "image": "cutout.image"},
                     "params": {"method": "learned"}},
            "edit": {"type": "pixgraph.PixelHeightEdit", "inputs": {"height": "fg_h.height", "mask": "cutout.alpha"}},
            "place": {"type": "pixgraph.PlaceCutout",
                      "inputs": {"cutout": "cutout.image", "background": "photo.image", "height": "edit.height"},
                      "params": {"foot": [round(fu * S, 3), round(fv * S, 3)], "scale": float(S)}},
            "bg_h": {"type": "pixgraph.LoadPixelHeight", "params": {"path": "bg_height.npy"}},
            "light": {"type": "pixgraph.Light", "inputs": {"camera": "cam.camera", "mask": "place.alpha"},
                      "params": {"azimuth": -35.0, "elevation": 40.0, "radius": 0.2}},
            "shadow": {"type": "pixgraph.SoftShadow",
                       "inputs": {"mask": "place.alpha", "fg_height": "place.height", "bg_height": "bg_h.height",
                                  "light": "light.light", "camera": "cam.camera"},
                       "params": {"samples": 48, "thickness": 6}},
            "comp": {"type": "pixgraph.Composite",
                     "inputs": {"background": "photo.image", "cutout": "place.image", "alpha": "place.alpha",
                                "shadow": "shadow.darkness"}},
        },
        "outputs": {"final": "comp.image"},
    }
    import yaml
    with open(os.path.join(dest, "scene.yaml"), "w") as f:
        yaml.safe_dump(graph, f, sort_keys=False)
    return {"graph": os.path.join(dest, "scene.yaml"), "object": meta["scene"]["object"], "true_h": true_h,
            "mask": mask, "ground": g}


def true_contacts(true_h: np.ndarray, mask: np.ndarray, k: int) -> list:
    """Up to ``k`` contact points (u, v) [px]: the lowest visible pixel whose true height is
    < 1 px in each of ``k`` equal column bins of those pixels (one bin: the lowest of all)."""
    ys, xs = np.nonzero(mask & (true_h < 1.0))
    if len(xs) == 0:
        ys, xs = np.nonzero(mask)
    edges = np.linspace(xs.min(), xs.max() + 1, k + 1)
    pts = []
    for a, b in zip(edges[:-1], edges[1:]):
        sel = (xs >= a) & (xs < b)
        if sel.any():
            i = np.argmax(np.where(sel, ys, -1))
            pts.append((float(xs[i] + 0.5), float(ys[i] + 0.5)))    # the pixel's centre: inside the mask
    return pts


#: the simulated user's plans: each a list of page actions (at most 3: drags, or a toggle)
PLANS = {
    "1 contact": ["contact:1"],
    "2 contacts": ["contact:2"],
    "3 contacts": ["contact:3"],
    "2 contacts, upright": ["contact:2", "upright"],
    "1 contact + top": ["contact:1", "top"],
    "2 contacts + top": ["contact:2", "top"],
    "top": ["top"],
    "lying": ["lying"],
}


def plan_params(plan: list, true_h: np.ndarray, mask: np.ndarray, edited_without_tilt) -> dict:
    """The edit's params after the plan's actions; ``top`` drags the tilt handle until the top's
    height is its true one (``edited_without_tilt(params)``: the edited map before it)."""
    from pixgraph_nodes.ops.height_edit import tilt_for_height, top_point
    p = {}
    for act in plan:
        if act.startswith("contact:"):
            p["contact_points"] = [c for pt in true_contacts(true_h, mask, int(act[8:])) for c in pt]
        elif act == "upright":
            p["contact_mode"] = "upright"
        elif act == "lying":
            p["lying"] = True
        elif act == "top":
            top = top_point(mask, edited_without_tilt(p))
            true_top = top_point(mask, true_h)
            if top is not None and true_top is not None:
                p["tilt"] = round(tilt_for_height(top[3], true_top[2], 0.0, 20.0), 2)
    return p


def shadow_rmse(graph: str, edit_params: dict, height: str, ground_region: np.ndarray | None = None) -> tuple:
    """(darkness, rmse vs the true heights' darkness) of the graph's shadow with the
    edit's params and the height source ``height`` ("learned", "contact_line", "true")."""
    from pixgraph.session import Session
    ses = _session()
    g = ses.load(graph)
    if height == "true":
        g = _with_true_height(ses, graph)
    params = {f"edit.{k}": v for k, v in edit_params.items()}
    params["fg_h.method"] = height if height in ("contact_line", "learned") else "learned"
    if height == "true":
        params.pop("fg_h.method")
    res = ses.run(g, outputs=["shadow.darkness", "place.alpha"], params=params)
    return res["shadow.darkness"], res["place.alpha"]


_SES = None


def _session():
    global _SES
    if _SES is None:
        from pixgraph.session import Session
        _SES = Session()
    return _SES


def _with_true_height(ses, graph: str):
    import yaml
    with open(graph) as f:
        doc = yaml.safe_load(f)
    doc["nodes"]["fg_h"] = {"type": "pixgraph.LoadPixelHeight", "params": {"path": "true_height.npy"}}
    path = graph.replace(".yaml", "_true.yaml")
    with open(path, "w") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    return ses.load(path)


def rmse_vs_true(graph: str, edit_params: dict, height: str) -> float:
    truth, alpha = shadow_rmse(graph, {}, "true")
    got, _ = shadow_rmse(graph, edit_params, height)
    keep = alpha < 0.02
    return float(np.sqrt(np.mean((got[keep] - truth[keep]) ** 2)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shadows", default=os.path.join(REPO, "data", "hreal", "wall_named64"))
    ap.add_argument("--samples", default="17,20,6")
    ap.add_argument("--shots", default=None, help="folder for page_height_before/after.png (first sample)")
    ap.add_argument("--explore", action="store_true", help="in-process only: the numbers of the planned edits")
    a = ap.parse_args(argv)
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}")
    rows = []
    for k, idx in enumerate(int(x) for x in a.samples.split(",")):
        sample = os.path.join(a.shadows, f"{idx:05d}.npz")
        with tempfile.TemporaryDirectory(prefix="pixgraph-hfix-") as d:
            sc = build_scene(sample, d)
            if a.explore:
                ses = _session()
                g = ses.load(sc["graph"])
                m = ses.run(g, outputs=["cutout.alpha"])["cutout.alpha"] > 0.5
                out = [f"{idx} {sc['object']}"]
                for method in ("contact_line", "learned"):
                    def before_tilt(p, method=method):
                        q = {f"edit.{k}": v for k, v in p.items() if k != "tilt"}
                        q["fg_h.method"] = method
                        return ses.run(g, outputs=["edit.height"], params=q)["edit.height"]
                    res = {"none": rmse_vs_true(sc["graph"], {}, method)}
                    for name, plan in PLANS.items():
                        res[name] = rmse_vs_true(sc["graph"], plan_params(plan, sc["true_h"], m, before_tilt), method)
                    best = min(res, key=res.get)
                    out.append(f"{method}: none {res['none']:.4f} best {best} {res[best]:.4f} ("
                               + ", ".join(f"{k} {v:.3f}" for k, v in res.items() if k != "none") + ")")
                print(" | ".join(out), flush=True)
                continue
    return 0


if __name__ == "__main__":
    sys.exit(main())
