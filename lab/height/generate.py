"""Cheap cutout renders for the pixel-height predictor: colour + alpha + pixel height.

    python -m pixgraph_lab.height.generate --split train --n 3000 --seed 0 --out data/height/train

Unlike the ground-truth benchmarks (``pixgraph_lab.datagen``) no shadow rays are
cast: per sample, the camera rays of every pixel centre (pixel height, mask) and a
2x2 sub-pixel grid (alpha) are intersected with the object alone, and the colour
is a shaded preview (albedo with a procedural texture x (0.25 + 0.75 cos) from a
random light direction, with self-shadowing: one shadow ray per object pixel).

Objects (``object_pool``): the pybullet ``random_urdfs`` meshes and procedural
shapes (box, cylinder, capsule, table, mushroom for training; figure and tee, a
post with a cross bar, for test). Splits, objects disjoint:

* ``test``: the datagen test objects (``objects.object_split == "test"``:
  ~20 % of the urdf meshes, figure) + ``proc:tee``;
* ``val``: train-split urdf meshes with ``sha256("val:" + id) mod 8 == 0``
  (so val objects are never in train either) and the train procedural kinds;
* ``train``: the remaining train-split objects.

Pose (``POSES``): ``upright`` (the mesh as modelled, y up), ``tilted`` (rotated
15-50 deg about a random horizontal axis), ``lying`` (90 deg), ``random``
(uniformly random 3D rotation, as in the benchmarks); then a random yaw, resting
on the ground Y = 0. A sample is an ``overhang`` when in more than 20 % of the
columns of its silhouette the lowest object pixel is more than 15 % of the
object's largest pixel height above the ground (a table top, a mushroom cap,
an arm: where a contact-line guess must be wrong).

Camera: our level camera (``nodes/ops/camera.Camera``) with hfov 30-70 deg and
camera height log-uniform 0.3-3 world units (objects are 0.3-1.6 tall), the
object's image height 0.2-0.75 of the image and its foot row 0.55-0.95 of the
image height (which sets depth and horizon).

Stored per sample ``NNNNN.npz``: ``rgb`` uint8 (H, W, 3) sRGB-encoded straight
(un-premultiplied) colour, ``alpha`` uint8 coverage, ``height`` float16 pixel
height of the visible surface [px] (0 outside the mask), ``mask`` bool (centre
ray hits), ``meta`` JSON. Sample ``i`` depends only on ``(seed, split, i)``;
existing files are skipped (resumable), ``--start`` shards.
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import math
import os
import sys
import time

import numpy as np

SPLIT_CODE = {"train": 1, "val": 3, "test": 2}
POSES = ("upright", "tilted", "lying", "random")
POSE_P = (0.35, 0.25, 0.2, 0.2)
PROC_TRAIN = ("proc:box", "proc:cylinder", "proc:capsule", "proc:table", "proc:mushroom")
PROC_TEST = ("proc:figure", "proc:tee")


def height_split(obj_id: str) -> str:
    """'train', 'val' or 'test' for an object id (module doc)."""
    from pixgraph_lab.datagen.objects import object_split
    if obj_id in PROC_TEST:
        return "test"
    if obj_id in PROC_TRAIN:
        return "train"
    if object_split(obj_id) == "test":
        return "test"
    d = int(hashlib.sha256(("val:" + obj_id).encode()).hexdigest(), 16)
    return "val" if d % 8 == 0 else "train"


def object_pool(split: str) -> tuple[list[str], list[str]]:
    """(urdf ids, procedural ids) of a split; val shares the train procedural kinds."""
    from pixgraph_lab.datagen.objects import urdf_object_ids
    urdfs = [i for i in urdf_object_ids() if height_split(i) == split]
    procs = list(PROC_TEST) if split == "test" else list(PROC_TRAIN)
    return urdfs, procs


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    x, y, z = axis
    c, s, C = math.cos(angle), math.sin(angle), 1 - math.cos(angle)
    return np.array([[c + x * x * C, x * y * C - z * s, x * z * C + y * s],
                     [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
                     [z * x * C - y * s, z * y * C + x * s, c + z * z * C]])


def _extra_procedural(kind, rng):
    import trimesh
    c = trimesh.creation

    def box(ext, at):
        m = c.box(extents=ext)
        m.apply_translation(at)
        return m

    parts = []
    if kind == "proc:table":
        w, d, h, t = rng.uniform(0.5, 1.4), rng.uniform(0.4, 1.0), rng.uniform(0.4, 1.0), rng.uniform(0.03, 0.12)
        leg = rng.uniform(0.03, 0.08)
        inset = rng.uniform(0.0, 0.25)
        parts.append(box([w, t, d], [0, h - t / 2, 0]))
        for sx in (-1, 1):
            for sz in (-1, 1):
                x = sx * (w / 2 - leg / 2 - inset * w / 2)
                z = sz * (d / 2 - leg / 2 - inset * d / 2)
                parts.append(box([leg, h - t, leg], [x, (h - t) / 2, z]))
    elif kind == "proc:mushroom":
        sh, sr = rng.uniform(0.3, 1.0), rng.uniform(0.04, 0.15)
        cr = rng.uniform(2.0, 5.0) * sr
        stem = c.cylinder(radius=sr, height=sh, sections=24)
        stem.apply_transform(_h(_rot([1, 0, 0], math.pi / 2)))
        stem.apply_translation([0, sh / 2, 0])
        cap = c.icosphere(subdivisions=2, radius=1.0)
        cap.apply_scale([cr, rng.uniform(0.3, 0.8) * cr, cr])
        cap.apply_translation([0, sh, 0])
        parts += [stem, cap]
    elif kind == "proc:tee":
        ph, pw = rng.uniform(0.5, 1.5), rng.uniform(0.05, 0.15)
        bl, bt = rng.uniform(0.4, 1.2), rng.uniform(0.05, 0.15)
        parts.append(box([pw, ph, pw], [0, ph / 2, 0]))
        parts.append(box([bl, bt, pw], [0, ph - bt / 2 - rng.uniform(0, 0.3) * ph, 0]))
        base = rng.uniform(0.15, 0.4)
        parts.append(box([base, 0.03, base], [0, 0.015, 0]))
    else:
        raise ValueError(kind)
    m = trimesh.util.concatenate(parts)
    return np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)


def _h(R):
    M = np.eye(4)
    M[:3, :3] = R
    return M


def raw_object(obj_id: str, rng: np.random.Generator):
    """Unposed mesh (V, F), y up, as modelled (urdf: z-up file turned y-up, stretched)."""
    if obj_id.startswith("urdf:"):
        from pixgraph_lab.datagen.objects import read_urdf_mesh
        V, F = read_urdf_mesh(obj_id)
        V = V[:, [0, 2, 1]] * np.array([1, 1, -1])          # z-up -> y-up
        V[:, 1] *= rng.uniform(1.0, 2.5)
        return V, F
    if obj_id in ("proc:table", "proc:mushroom", "proc:tee"):
        return _extra_procedural(obj_id, rng)
    from pixgraph_lab.datagen.objects import _procedural
    return _procedural(obj_id, rng)


def pose_object(V, pose: str, rng: np.random.Generator, height_range=(0.3, 1.6)):
    """Rotate by ``pose`` (module doc), random yaw, scale to a random height, rest on Y = 0."""
    from pixgraph_lab.datagen.objects import _random_rotation
    V = V - V.mean(0)
    if pose == "tilted" or pose == "lying":
        a = rng.uniform(0, 2 * math.pi)
        ang = math.radians(rng.uniform(15, 50)) if pose == "tilted" else math.pi / 2
        if pose == "lying":
            V = V @ _rot([0, 1, 0], rng.uniform(0, 2 * math.pi)).T
        V = V @ _rot([math.cos(a), 0, math.sin(a)], ang).T
    elif pose == "random":
        V = V @ _random_rotation(rng).T
    return stand(V, rng, height_range)


def stand(V, rng: np.random.Generator, height_range):
    """A posed object turned about the vertical by a random yaw, scaled to a random
    height in ``height_range`` (world units) and stood on the ground (lowest Y = 0),
    centred on the vertical axis."""
    from pixgraph_lab.datagen.objects import _yaw

    V = V @ _yaw(rng.uniform(0, 2 * math.pi)).T
    lo, hi = V.min(0), V.max(0)
    V = V * (rng.uniform(*height_range) / (hi[1] - lo[1]))
    lo, hi = V.min(0), V.max(0)
    return V - np.array([(lo[0] + hi[0]) / 2, lo[1], (lo[2] + hi[2]) / 2])


def is_overhang(mask, height) -> bool:
    """Module doc: the silhouette's bottom is off the ground in > 20 % of its columns."""
    cols = mask.any(0)
    if not cols.any():
        return False
    H = mask.shape[0]
    bottom = H - 1 - np.argmax(mask[::-1], axis=0)
    hb = height[bottom, np.arange(mask.shape[1])][cols]
    return float((hb > 0.15 * height.max()).mean()) > 0.2


def srgb_encode(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def render_cutout(camera, V, F, rng: np.random.Generator, subsamples: int = 2):
    """(rgb float linear straight colour, alpha, mask, height [px]) of the object alone."""
    from pixgraph_lab.datagen.raycast import RayScene
    scene = RayScene([(V, F)])
    W, H, f = camera.width, camera.height, camera.focal
    u, v = camera.pixel_grid()
    o = np.array([0.0, camera.cam_height, 0.0])

    def cast(uu, vv):
        d = camera.ray(uu.ravel(), vv.ravel())
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        t, p, n = scene.intersect(np.broadcast_to(o, d.shape), d)
        return d, t, p, n

    d, t, p, n = cast(u, v)
    hit = np.isfinite(t)
    cov = np.zeros(H * W)
    offs = (np.arange(subsamples) + 0.5) / subsamples - 0.5
    for dy in offs:
        for dx in offs:
            cov += np.isfinite(cast(u + dx, v + dy)[1])
    alpha = cov / subsamples ** 2
    idx = np.nonzero(hit)[0]
    P, N = p[idx], n[idx]
    N = np.where((np.sum(N * d[idx], 1) > 0)[:, None], -N, N)
    height = np.zeros(H * W)
    height[idx] = f * P[:, 1] / (-P[:, 2])
    # shading: a random light direction from the upper hemisphere, self-shadowed
    el, az = math.radians(rng.uniform(10, 80)), rng.uniform(0, 2 * math.pi)
    L = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    cos = np.clip(N @ L, 0, 1)
    vis = ~scene.occluded(P + N * 1e-4, np.broadcast_to(L, P.shape), None)
    albedo = rng.uniform(0.1, 0.95, 3)
    k = rng.normal(size=(3, 3)) * rng.uniform(2, 25)
    tex = 1.0 + rng.uniform(0, 0.5) * np.sin(P @ k.T + rng.uniform(0, 6.3, 3))
    albedo2 = rng.uniform(0.1, 0.95, 3)
    mix = (np.sin(P @ rng.normal(size=3) * rng.uniform(1, 10)) > rng.uniform(-1, 1))[:, None] \
        if rng.random() < 0.4 else np.zeros((len(P), 1), bool)
    alb = np.where(mix, albedo2, albedo) * tex
    amb = rng.uniform(0.15, 0.4)
    rgb = np.zeros((H * W, 3))
    rgb[idx] = np.clip(alb * (amb + (1 - amb) * (cos * vis))[:, None], 0, 1)
    # pixels covered only at sub-pixel positions: spread the nearest colour in
    rgb = rgb.reshape(H, W, 3)
    m = hit.reshape(H, W)
    edge = (alpha.reshape(H, W) > 0) & ~m
    if edge.any():
        from scipy.ndimage import distance_transform_edt
        _, (iy, ix) = distance_transform_edt(~m, return_indices=True)
        rgb[edge] = rgb[iy[edge], ix[edge]]
    return rgb, alpha.reshape(H, W), m, height.reshape(H, W)


def make_sample(split: str, index: int, seed: int = 0, res: int = 256, mix: str = "v2",
                category: str | None = None):
    """One sample of ``split``. ``mix``: ``v2`` (the random-shape mix of the second model,
    unchanged) or ``real`` (``pixgraph_lab.height.real``: people, animals, figurines,
    furniture, products, vehicles; test = pybullet_data's named meshes)."""
    if mix in ("real", "real_organic"):
        from .real import make_real_sample
        return make_real_sample(split, index, seed, res, mix, category)
    if category is not None:
        raise ValueError("--category needs --mix real or real_organic")
    from pixgraph_nodes.ops.camera import Camera
    rng = np.random.default_rng([seed, 7, SPLIT_CODE[split], index])
    urdfs, procs = object_pool(split)
    t0 = time.perf_counter()
    for tries in range(1, 200):
        obj = urdfs[rng.integers(len(urdfs))] if rng.random() >= 0.3 else procs[rng.integers(len(procs))]
        pose = str(rng.choice(POSES, p=POSE_P))
        try:
            V0, F = raw_object(obj, rng)
        except ValueError:
            continue
        V = pose_object(V0, pose, rng)
        cam = Camera(res, res, hfov=float(rng.uniform(30, 70)), horizon=0.0,
                     cam_height=float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))))
        placed = _place(cam, V, rng)
        if placed is None:
            continue
        cam, PV = placed
        rgb, alpha, mask, height = render_cutout(cam, PV, F, rng)
        if mask.sum() < 0.004 * res * res or mask[0].any() or mask[-1].any() or mask[:, 0].any() \
                or mask[:, -1].any():
            continue
        meta = {"split": split, "index": index, "rng": [seed, 7, SPLIT_CODE[split], index],
                "object": obj, "pose": pose, "overhang": is_overhang(mask, height),
                "camera": cam.to_dict(), "object_height": float(V[:, 1].max()),
                "mask_px": int(mask.sum()), "tries": tries, "seconds": time.perf_counter() - t0}
        arrays = {"rgb": np.round(srgb_encode(rgb) * 255).astype(np.uint8),
                  "alpha": np.round(alpha * 255).astype(np.uint8), "mask": mask,
                  "height": height.astype(np.float16)}
        return arrays, meta
    raise RuntimeError(f"sample {index}: no valid scene in 200 tries")


def _place(camera, V, rng):
    """Depth, lateral offset and horizon so the object fits (image height 0.2-0.75)."""
    W, H, f = camera.width, camera.height, camera.focal
    ht = float(V[:, 1].max())
    for _ in range(50):
        D = f * ht / (rng.uniform(0.2, 0.75) * H)
        D = max(D, 0.3 + float(np.abs(V[:, [0, 2]]).max()))
        x = (rng.uniform(0.3, 0.7) * W - W / 2) * D / f
        v_foot = rng.uniform(0.55, 0.95) * H
        cam = dataclasses.replace(camera, horizon=float(v_foot - f * camera.cam_height / D))
        P = V + np.array([x, 0.0, -D])
        uvh, depth = cam.project(P)
        if (depth > 0.1).all() and uvh[:, 0].min() > 3 and uvh[:, 0].max() < W - 3 \
                and uvh[:, 1].min() > 3 and uvh[:, 1].max() < H - 3:
            return cam, P
    return None


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.generate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--split", choices=sorted(SPLIT_CODE), required=True)
    ap.add_argument("--n", type=int, required=True)
    ap.add_argument("--start", type=int, default=0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--out", required=True)
    ap.add_argument("--threads", type=int, default=1, help="Dr.Jit worker threads")
    ap.add_argument("--mix", choices=("v2", "real", "real_organic"), default="v2",
                    help="object mix: v2 = random shapes (the second model), real = things people cut out "
                         "(pixgraph_lab.height.real), real_organic = real plus 20 %% smooth rounded things")
    ap.add_argument("--category", default=None,
                    help="with --mix real*: only this procedural category (e.g. organic; train/val only)")
    a = ap.parse_args(argv)
    from pixgraph_lab.datagen.raycast import select_variant
    variant = select_variant()
    import drjit as dr
    dr.set_thread_count(a.threads)
    os.makedirs(a.out, exist_ok=True)
    t0, made = time.perf_counter(), 0
    for i in range(a.start, a.start + a.n):
        p = os.path.join(a.out, f"{i:05d}.npz")
        if os.path.exists(p):
            continue
        arrays, meta = make_sample(a.split, i, a.seed, a.res, a.mix, a.category)
        tmp = p + ".tmp"
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, meta=np.array(json.dumps(meta)), **arrays)
        os.replace(tmp, p)
        made += 1
        if made % 50 == 0:
            dt = time.perf_counter() - t0
            print(f"{a.split}: {made} new, {dt / made:.3f} s/sample", flush=True)
    dt = time.perf_counter() - t0
    cfg = {"command": " ".join(["python -m pixgraph_lab.height.generate"] + (argv or sys.argv[1:])),
           "split": a.split, "n": a.n, "start": a.start, "seed": a.seed, "res": a.res, "mix": a.mix,
           "category": a.category,
           "mitsuba_variant": variant, "new_samples": made, "seconds": dt}
    with open(os.path.join(a.out, f"config_{a.start}.json"), "w") as fh:
        json.dump(cfg, fh, indent=1)
    print(f"{made} new samples in {dt:.1f} s ({dt / max(made, 1):.3f} s/sample, variant {variant}) in {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
