"""Fixing a wrong pixel height by hand in the page, on the repo's own real-photo check
examples (docs/height.md, "The real-photo check: where each method fails": our Mitsuba renders of held-out
named meshes with exact pixel heights), in headless Chromium, in at most 3 drags.

    python benchmarks/page_height_fix.py --shadows data/hreal/wall_named64 \\
        [--samples 23:learned,21:contact_line,5:contact_line] [--shots docs/img]

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

The simulated user (rules written before any measurement, like real_photos.py's; its
plans and their params are ``pixgraph_lab.height.edit_plans``, shared with real_photos.py):
it knows where the object really touches the ground and how tall its top and its
body really are (``known_heights``), and tries each plan of at most 3 page actions
in ``PLANS`` (contact points dragged from the foot's hollow handle onto the lowest
visible pixel with true height < 1 px in each of k column bins; the tilt handle
dragged until the top's height is its true one, lying down the same square for the
thickness; the body's ring (foot depth) dragged until the body point's height is
its true one; the upright and lying toggles; the other height method), keeping the plan whose shadow is
closest to the true heights' shadow (the user sees the shadow). That plan is then
done in the page, in headless Chromium, each action a pointer drag (or a toggle)
through the page's own handles, waiting for the previews and the final; the
edit's params are read back from the server and the shadow compared, in-process
at full size, with the shadow of the *true* heights through the same graph: RMSE
of the darkness and IoU of the shadow regions (darkness > 0.3) over the pixels
outside the cutout, before (the height as predicted) and after.

Writes ``page_height_fix.png`` (before and after in the page, handles included,
and the true heights' composite) for the first sample into --shots, and prints a
markdown table. ``--explore 23,21`` prints every plan's numbers instead (no page).

``--users A,B`` (with ``--explore``) and ``--user B`` (the page): user B does the same
actions but drags the top's square and the body's ring to the height, of a fixed set
and user A's, whose shadow comes closest (``edit_plans``; docs/height-record.md, "Rules
fixed before measuring: a user who watches the shadow").
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

# the simulated user (its plans and their params), shared with docs/height.md's real-photo check
from pixgraph_lab.height.edit_plans import (NEW_PLANS, OTHER, PLANS, known_heights, plan_method,  # noqa: E402,F401
                                            plan_params, true_contacts)

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
S = 2   # the scene's size / the sample's


def _srgb8(x):
    x = np.clip(x, 0, 1)
    return (np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055) * 255 + 0.5).astype(np.uint8)


def build_scene(sample: str, dest: str, method: str = "learned") -> dict:
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
                     "params": {"method": method}},
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
    # the coverage as the graph reads it back (8-bit alpha > 0.5): the user's pixels and the edit's
    seen = cut[..., 3].astype(np.float32) / 255.0 > 0.5
    return {"graph": os.path.join(dest, "scene.yaml"), "object": meta["scene"]["object"],
            "true_h": np.where(seen, true_h, 0.0), "known_h": known_heights(true_h, mask.astype(bool), seen),
            "mask": seen, "method": method}


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


def iou(a: np.ndarray, b: np.ndarray, keep: np.ndarray, level: float = 0.3) -> float:
    """IoU of the two shadows' regions (darkness > level) over the pixels ``keep``."""
    x, y = (a > level) & keep, (b > level) & keep
    return float((x & y).sum() / max(1, (x | y).sum()))


_TRUTH = {}


def measure(graph: str, params: dict, method: str) -> dict:
    """RMSE and IoU of the shadow with ``params`` and height ``method`` vs the true heights'."""
    if graph not in _TRUTH:
        _TRUTH[graph] = shadow_rmse(graph, {}, "true")
    truth, alpha = _TRUTH[graph]
    got, _ = shadow_rmse(graph, params, method)
    keep = alpha < 0.02
    return {"rmse": float(np.sqrt(np.mean((got[keep] - truth[keep]) ** 2))), "iou": iou(got, truth, keep)}


def edited_map(graph: str, params: dict, method: str) -> np.ndarray:
    """The ``PixelHeightEdit`` node's output [px] with the edit's ``params`` on the
    ``method`` height (the session's memory cache answers a repeat)."""
    ses = _session()
    q = {f"edit.{k}": v for k, v in params.items()}
    q["fg_h.method"] = method
    return ses.run(ses.load(graph), outputs=["edit.height"], params=q)["edit.height"]


def choose_plan(sc: dict, method: str, user: str = "A") -> tuple[str, dict, dict]:
    """The plan (PLANS) whose shadow is closest to the true heights' (the user sees the
    shadow): its name, params and numbers; and the numbers of every plan. ``user``: A drags
    each handle to the true height, B to the height whose shadow is closest (``edit_plans``'
    ``watch``); every plan's entry is (params, numbers, the drags' handle heights)."""
    m = sc["mask"]
    every = {"none": ({}, measure(sc["graph"], {}, method), {})}
    for name, plan in PLANS.items():
        meth = plan_method(plan, method)

        def watch(cands, meth=meth):
            return int(np.argmin([measure(sc["graph"], c, meth)["rmse"] for c in cands]))
        targets = {}
        p = plan_params(plan, sc["known_h"], m, lambda q: edited_map(sc["graph"], q, meth), watch=watch if user == "B" else None,
                        targets=targets)
        every[name] = (p, measure(sc["graph"], p, meth), targets)
    best = min(every, key=lambda k: every[k][1]["rmse"])
    return best, every[best][0], every


def in_page(url: str, plan: list, sc: dict, page_shot: str | None, targets: dict | None = None) -> tuple:
    """The plan's actions done in the page (headless Chromium): drags of the foot's hollow
    handle to each contact point, of the tilt handle to the top's true height (or to
    ``targets``' height, user B's: by param name, ``choose_plan``'s), toggles.
    Returns the edit's params after, the number of pointer drags and toggles, the
    before/after crops of the stage, and the previews' times (pointer -> painted, ms)."""
    import httpx
    from PIL import Image

    from pixgraph_nodes.ops.height_edit import body_point, top_point
    sys.path.insert(0, os.path.join(REPO, "tests"))
    from serve_helpers import chromium_browser  # noqa: E402
    from test_page_photo import centre, drag, last_seq, open_page, screen, wait_final  # noqa: E402

    shots, actions = [], 0
    with chromium_browser() as b:
        page, errors = open_page(b, url)
        k = page.evaluate("window.pixgraphView.state.k")

        def crop():
            import io
            png = page.locator("#stage").screenshot()
            img = Image.open(io.BytesIO(png)).convert("RGB")
            x0, y0 = page.evaluate("window.pixgraphView.toScreen(0, 0)")
            x1, y1 = page.evaluate("window.pixgraphView.toScreen(512, 512)")
            return img.crop((round(x0), round(y0), round(x1), round(y1)))

        shots.append(crop())
        e = httpx.get(url + "/api/scene", timeout=120).json()["height_edit"]
        sx, tx, sy, ty = e["frame"]
        m = sc["mask"]
        for act in plan:
            if act.startswith("contact:"):
                for (cu, cv) in true_contacts(sc["known_h"], m, int(act[8:])):
                    drag(page, centre(page, "#contact-new"), screen(page, sx * cu + tx, sy * cv + ty))
                    actions += 1
            elif act in ("top", "thickness", "depth"):
                # the top's square (tilt; lying: thickness) or the body's ring (foot depth), dragged
                # up or down until the point's height is the true one
                e = httpx.get(url + "/api/scene", timeout=120).json()["height_edit"]
                point, have, sel = ((body_point(m, sc["known_h"]), e["body"], "#depth-handle") if act == "depth"
                                    else (top_point(m, sc["known_h"]), e["top"], "#tilt-handle"))
                want = point[2] if targets is None else targets[{"top": "tilt", "depth": "foot_depth"}.get(act, act)]
                x, y = centre(page, sel)
                drag(page, (x, y), (x, y - (want - have[2]) * sy * k))
                actions += 1
            elif act == "switch":
                seq = last_seq(page)
                sel = page.locator('[data-param="fg_h.method"]')
                if not sel.is_visible():     # the node's box in the panel is closed: open it (a click)
                    page.locator("details.node", has=sel).locator("summary").click()
                    actions += 1             # a page action too (PLANS count the switch as one)
                sel.select_option(OTHER[sc["method"]])
                wait_final(page, seq)
                actions += 1
            elif act in ("upright", "lying"):
                seq = last_seq(page)
                page.check(f"#{act}")
                wait_final(page, seq)
                actions += 1
        shots.append(crop())
        nodes = {n["id"]: n["values"] for n in httpx.get(url + "/api/graph", timeout=120).json()["nodes"]}
        vals = dict(nodes["edit"], method=nodes["fg_h"]["method"])
        page.wait_for_function("window.pixgraphShown.every(s => s.painted_ms !== undefined)", timeout=60000)
        painted = page.evaluate("window.pixgraphShown.filter(s => s.kind === 'move').map(s => s.painted_ms)")
        assert not errors, errors
        page.close()
    return vals, actions, shots, painted


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shadows", default=os.path.join(REPO, "data", "hreal", "wall_named64"))
    ap.add_argument("--samples", default="23:learned,21:contact_line,5:contact_line",
                    help="index:height method of the samples to fix in the page")
    ap.add_argument("--shots", default=None, help="folder for page_height_fix.png (the first sample)")
    ap.add_argument("--explore", default=None, help="indices: print every plan's numbers, no page")
    ap.add_argument("--users", default="A", help="--explore: the simulated users, A and/or B (e.g. A,B): A drags "
                    "each handle to the true height, B to the height whose shadow is closest")
    ap.add_argument("--user", default="A", choices=("A", "B"), help="the simulated user whose plan the page does")
    a = ap.parse_args(argv)
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}")
    if a.explore:
        users = a.users.split(",")
        gains = {u: [] for u in users}
        old_gains, zero, rows = [], [], []
        for idx in (int(x) for x in a.explore.split(",")):
            with tempfile.TemporaryDirectory(prefix="pixgraph-hfix-") as d:
                sc = build_scene(os.path.join(a.shadows, f"{idx:05d}.npz"), d)
                for method in ("contact_line", "learned"):
                    for user in users:
                        best, _, every = choose_plan(sc, method, user)
                        before, after = every["none"][1], every[best][1]

                        def removed(rmse):   # no shadow error to remove (no shadow outside the cutout): 0 % removed
                            return 1 - rmse / before["rmse"] if before["rmse"] > 0 else 0.0
                        gains[user].append(removed(after["rmse"]))
                        if user == users[0]:
                            old_gains.append(removed(min(v[1]["rmse"] for k, v in every.items()
                                                         if k not in NEW_PLANS)))
                            zero.append(before["rmse"] == 0)
                        rows.append(f"| {idx} {sc['object'].removeprefix('named:')} | {method.replace('_', ' ')} | "
                                    f"{user} | {best} | {before['rmse']:.3f} -> {after['rmse']:.3f} "
                                    f"({gains[user][-1]:.0%}) | {before['iou']:.2f} -> {after['iou']:.2f} |")
                        print(f"{idx} {sc['object']} {method} user {user}: best {best} {before['rmse']:.3f} -> "
                              f"{after['rmse']:.3f} ({gains[user][-1]:.0%}), IoU {before['iou']:.2f} -> "
                              f"{after['iou']:.2f}; " + ", ".join(f"{k} {v[1]['rmse']:.3f}/{v[1]['iou']:.2f}"
                                                                  for k, v in every.items()), flush=True)
        print("| sample | height | user | best plan (<= 3 actions) | shadow RMSE vs true heights' | IoU |")
        print("|---|---|---|---|---|---|")
        for row in rows:
            print(row)
        for user in users:
            g = np.array(gains[user])
            print(f"user {user}: best plan of <= 3 actions over {len(g)} cases: median {np.median(g):.0%} of the "
                  f"shadow's RMSE removed (min {g.min():.0%}, max {g.max():.0%}); >= 50 % in "
                  f"{int((g >= 0.5).sum())}, >= 30 % in {int((g >= 0.3).sum())}; load average "
                  f"{os.getloadavg()[0]:.2f}")
            if any(zero):
                z = ~np.array(zero)
                print(f"  {int((~z).sum())} case(s) with no shadow error before (counted as 0 % removed above); "
                      f"without them: median {np.median(g[z]):.0%}, >= 30 % in {int((g[z] >= 0.3).sum())} of "
                      f"{int(z.sum())}")
        o = np.array(old_gains)
        print(f"user {users[0]} without the plans of NEW_PLANS (foot depth, lying thickness): median "
              f"{np.median(o):.0%} (min {o.min():.0%}, max {o.max():.0%}); >= 30 % in {int((o >= 0.3).sum())}")
        return 0
    sys.path.insert(0, os.path.join(REPO, "tests"))
    from serve_helpers import running_server  # noqa: E402
    print("| sample | height | plan (page actions) | RMSE vs true-height shadow: before -> after (planned) "
          "| IoU: before -> after |")
    print("|---|---|---|---|---|")
    previews = []
    for n, item in enumerate(a.samples.split(",")):
        idx, method = item.split(":")
        with tempfile.TemporaryDirectory(prefix="pixgraph-hfix-") as d:
            sc = build_scene(os.path.join(a.shadows, f"{int(idx):05d}.npz"), d, method)
            best, planned, every = choose_plan(sc, method, a.user)
            with running_server(sc["graph"]) as (url, _):
                vals, actions, shots, painted = in_page(url, PLANS.get(best, []), sc, a.shots if n == 0 else None,
                                                        every[best][2] if a.user == "B" else None)
                previews += painted
            params = {k: vals[k] for k in ("contact_points", "contact_mode", "tilt", "lying", "thickness",
                                           "foot_depth")}
            before, after = every["none"][1], measure(sc["graph"], params, vals["method"])
            print(f"| {idx} {sc['object']} | {method} | {best} ({actions}) | {before['rmse']:.4f} -> "
                  f"**{after['rmse']:.4f}** ({every[best][1]['rmse']:.4f}) | {before['iou']:.2f} -> "
                  f"{after['iou']:.2f} |", flush=True)
            if a.shots and n == 0:
                write_figure(sc, shots, os.path.join(a.shots, "page_height_fix.png"))
    if previews:
        import statistics
        print(f"previews while dragging the handles (512x512 scene, the soft shadow's preview stand-in): median "
              f"{statistics.median(previews):.0f} ms pointer -> painted, {len(previews)} images; load average "
              f"{os.getloadavg()[0]:.2f}")
    return 0


def write_figure(sc: dict, shots, path: str) -> None:
    """Before | after (the page's image, handles included) | the true heights' composite."""
    from PIL import Image
    ses = _session()
    truth = ses.run(_with_true_height(ses, sc["graph"]), outputs=["final"])["final"]
    true_img = Image.fromarray(_srgb8(truth[..., :3]))
    w = 300
    panels = [im.resize((w, w), Image.LANCZOS) for im in (*shots, true_img)]
    fig = Image.new("RGB", (w * len(panels) + 8 * (len(panels) - 1), w), (30, 31, 34))
    for i, p in enumerate(panels):
        fig.paste(p, (i * (w + 8), 0))
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fig.save(path, optimize=True)
    print(f"wrote {path}")


if __name__ == "__main__":
    sys.exit(main())
