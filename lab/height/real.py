"""Cutout renders like real cutouts (``generate --mix real``): things people cut out of photos.

Objects:

* ``train`` / ``val``: the procedural categories of ``pixgraph_lab.datagen.categories``
  (person, animal, figurine, furniture, product, vehicle; 85 %) and the second
  model's random shapes (``generate``'s v2 object pool of that split: random_urdfs
  meshes and procedural blocks; 15 %, so what it learned is not forgotten). Val
  draws the same generators with other seeds (split code 3) and the v2 pool's
  val meshes, so no val mesh is a train mesh.
* ``test``: pybullet_data's *named* meshes (``NAMED``: duck, teddy, bunny, mug,
  table, lego brick, soccer ball, torus, tray), never used in train or val; their
  categories (toys, tableware, a ball, a brick) are not among the procedural ones
  except the table.

Pose: upright 80 % (as built / as modelled), tilted 5-25 deg about a random
horizontal axis 10 %, lying (90 deg) 6 %, random 3D rotation 4 %; then a random
yaw, resting on Y = 0. Camera and placement as ``generate`` (level camera, hfov
30-70 deg, the object 0.2-0.75 of the image high, its foot at 0.55-0.95).

Look: a material per part (skin tones for skin; random hue/saturation/value
elsewhere; stripes or noise texture on some), a sun with self-shadowing, a sky
ambient term brighter on up-facing surfaces, a weak fill light, Blinn-Phong
specular, a contact darkening near the ground, a random exposure and white
balance. Alpha: 2x2 sub-pixel coverage, then like matting output: blurred
(sigma 0.3-1.2 px, 60 %) and its threshold moved (erode/dilate by a fraction of
a pixel, 30 %). Colour: photo degradations: blur (30 %), Gaussian noise (0-3 %),
JPEG quality 40-95 (60 %). ``height`` and ``mask`` stay exact (centre rays).

``--mix real_organic`` draws the same categories in the same proportions scaled by
0.8 plus 20 % ``organic`` (smooth rounded things, ``categories.organic``; poses
upright 70 %, tilted 15 %, lying 10 %, random 5 %); ``--category organic`` makes
samples of that category only (how the fifth candidate's extra data was made).

Sample ``i`` depends only on ``(seed, split, i)`` (``default_rng([seed, 11, split, i])``;
with ``--category C``: ``default_rng([seed, 13, split, i, CATEGORIES.index(C)])``).
"""
from __future__ import annotations

import colorsys
import functools
import io
import math
import os
import time

import numpy as np

from .generate import (SPLIT_CODE, _place, _rot, is_overhang, object_pool, raw_object, stand,
                       srgb_encode)

NAMED = {   # id: (file under pybullet_data, up axis of the file)
    "named:duck": ("duck.obj", "y"),
    "named:teddy": ("teddy2_VHACD_CHs.obj", "y"),
    "named:bunny": ("bunny.obj", "y"),
    "named:mug": ("objects/mug.obj", "z"),
    "named:table": (None, "z"),          # table.urdf: a top and four legs of table/table.obj (a cube)
    "named:lego": ("lego/lego.obj", "y"),
    "named:soccerball": ("soccerball.obj", "y"),
    "named:torus": ("torus/torus_textured.obj", "y"),
    "named:tray": ("tray/tray_textured2.obj", "z"),
}
CATEGORY_P_REAL = {"person": 0.3, "animal": 0.15, "figurine": 0.15, "furniture": 0.17, "product": 0.13,
                   "vehicle": 0.1}   # --mix real: the fourth model's data (unchanged, so it regenerates)
ORGANIC_SHARE = 0.2
# --mix real_organic: the same categories in the same proportions, plus 20 % organic
CATEGORY_P = {**{k: v * (1 - ORGANIC_SHARE) for k, v in CATEGORY_P_REAL.items()}, "organic": ORGANIC_SHARE}
REAL_POSES = ("upright", "tilted", "lying", "random")
REAL_POSE_P = (0.8, 0.1, 0.06, 0.04)
ORGANIC_POSE_P = (0.7, 0.15, 0.1, 0.05)   # rounded things lean and lie more often


@functools.lru_cache(maxsize=None)
def named_mesh(obj_id: str):
    """(V, F) y up of a named pybullet_data mesh (module doc), as modelled."""
    import pybullet_data
    import trimesh
    path, up = NAMED[obj_id]
    root = pybullet_data.getDataPath()
    if path is None:   # the table of table/table.urdf: scaled unit cubes
        cube = trimesh.load(os.path.join(root, "table", "table.obj"), force="mesh", process=False)
        parts = []
        for scale, at in [((1.5, 1, 0.05), (0, 0, 0.6))] + [((0.1, 0.1, 0.58), (x, y, 0.29))
                                                              for x in (-0.65, 0.65) for y in (-0.4, 0.4)]:
            m = cube.copy()
            m.apply_scale(scale)
            m.apply_translation(at)
            parts.append(m)
        m = trimesh.util.concatenate(parts)
    else:
        m = trimesh.load(os.path.join(root, path), force="mesh", process=False)
    V = np.asarray(m.vertices, np.float64)
    if up == "z":
        V = V[:, [0, 2, 1]] * np.array([1, 1, -1])
    V[:, 1] -= V[:, 1].min()
    return V, np.asarray(m.faces, np.int64)


def pose_real(V, pose, rng, height_range=(0.3, 1.6)):
    """Rotate by ``pose`` (module doc), random yaw, scale to a random height, rest on Y = 0."""
    from pixgraph_lab.datagen.objects import _random_rotation
    V = V - V.mean(0)
    if pose in ("tilted", "lying"):
        a = rng.uniform(0, 2 * math.pi)
        ang = math.radians(rng.uniform(5, 25)) if pose == "tilted" else math.pi / 2
        V = V @ _rot([math.cos(a), 0, math.sin(a)], ang).T
    elif pose == "random":
        V = V @ _random_rotation(rng).T
    return stand(V, rng, height_range)


def _palette(names, rng):
    """Per material slot: (albedo (3,) linear, specular, shininess, texture params or None)."""
    mats = []
    for n in names:
        if n == "skin":
            h, s, v = rng.uniform(0.02, 0.09), rng.uniform(0.25, 0.6), rng.uniform(0.3, 0.95)
        elif n in ("tyre", "sole"):
            h, s, v = rng.uniform(0, 1), rng.uniform(0, 0.2), rng.uniform(0.05, 0.25)
        elif n == "hair":
            h, s, v = rng.uniform(0.02, 0.12), rng.uniform(0.2, 0.8), rng.uniform(0.05, 0.8)
        else:
            h, s, v = rng.uniform(0, 1), rng.uniform(0, 0.9) ** 1.5, rng.uniform(0.08, 0.95)
        srgb = np.array(colorsys.hsv_to_rgb(h, s, v))
        alb = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
        spec = rng.uniform(0, 0.5) ** 2 * (2.0 if n in ("metal", "glass", "paint", "cap", "plastic") else 1.0)
        shin = float(np.exp(rng.uniform(np.log(6), np.log(150))))
        tex = None
        if rng.random() < 0.35:
            tex = (rng.normal(size=3) * rng.uniform(5, 60), rng.uniform(0.1, 0.6), rng.uniform(0, 6.3),
                   rng.random() < 0.5)
        mats.append((alb, spec, shin, tex))
    return mats


def _prim_hits(scene, o, d):
    """First hits (t, normal, face index) of rays o + t d against a one-mesh RayScene."""
    si = scene._scene.ray_intersect(scene._rays(o, d, None))
    valid = np.array(si.is_valid(), bool)
    t = np.where(valid, np.array(si.t, np.float64), np.inf)
    n = np.array(si.n, np.float64).T
    prim = np.array(si.prim_index, np.int64)
    return t, n, np.where(valid, prim, -1)


def render_real(camera, V, F, face_slot, names, rng, subsamples=2):
    """(rgb linear straight, alpha, mask, height [px]) with the module doc's look."""
    from scipy.ndimage import distance_transform_edt, gaussian_filter

    from pixgraph_lab.datagen.raycast import RayScene
    scene = RayScene([(V, F)])
    W, H, f = camera.width, camera.height, camera.focal
    u, v = camera.pixel_grid()
    o = np.array([0.0, camera.cam_height, 0.0])

    def rays(uu, vv):
        d = camera.ray(uu.ravel(), vv.ravel())
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    d = rays(u, v)
    O = np.broadcast_to(o, d.shape)
    t, n, prim = _prim_hits(scene, O, d)
    hit = np.isfinite(t)
    cov = np.zeros(H * W)
    offs = (np.arange(subsamples) + 0.5) / subsamples - 0.5
    for dy in offs:
        for dx in offs:
            cov += np.isfinite(scene.intersect(O, rays(u + dx, v + dy))[0])
    alpha = (cov / subsamples ** 2).reshape(H, W)
    idx = np.nonzero(hit)[0]
    P = o + t[idx, None] * d[idx]
    N = n[idx]
    N = np.where((np.sum(N * d[idx], 1) > 0)[:, None], -N, N)
    height = np.zeros(H * W)
    height[idx] = f * P[:, 1] / (-P[:, 2])
    el, az = math.radians(rng.uniform(10, 80)), rng.uniform(0, 2 * math.pi)
    L = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    cos = np.clip(N @ L, 0, 1)
    vis = ~scene.occluded(P + N * 1e-4, np.broadcast_to(L, P.shape), None)
    mats = _palette(names, rng)
    slot = face_slot[prim[idx]]
    alb = np.stack([mats[s][0] for s in range(len(mats))])[slot]
    spec = np.array([m[1] for m in mats])[slot]
    shin = np.array([m[2] for m in mats])[slot]
    for s, m in enumerate(mats):
        if m[3] is None:
            continue
        k, amp, ph, stripes = m[3]
        sel = slot == s
        w = np.sin(P[sel] @ k + ph)
        alb[sel] = alb[sel] * (1.0 + amp * (np.sign(w) if stripes else w))[:, None]
    sun = rng.uniform(0.6, 1.0) * (1 + rng.uniform(-0.15, 0.15, 3))
    sky = rng.uniform(0.15, 0.45) * (1 + rng.uniform(-0.2, 0.2, 3))
    fillL = np.array([-L[0], rng.uniform(0.1, 0.6), -L[2]])
    fillL /= np.linalg.norm(fillL)
    fill = rng.uniform(0, 0.2)
    Vd = -d[idx]
    Hh = L + Vd
    Hh /= np.linalg.norm(Hh, axis=1, keepdims=True)
    sp = spec * np.clip(np.sum(N * Hh, 1), 0, 1) ** shin * vis * (cos > 0)
    obj_h = max(float(V[:, 1].max()), 1e-6)
    ao = 1.0
    if rng.random() < 0.7:
        ao = 0.55 + 0.45 * np.clip(P[:, 1] / (rng.uniform(0.03, 0.15) * obj_h), 0, 1)
    lin = alb * ((cos * vis)[:, None] * sun + ((0.55 + 0.45 * N[:, 1]) * ao)[:, None] * sky
                 + (fill * np.clip(N @ fillL, 0, 1))[:, None]) + sp[:, None] * sun
    lin *= float(np.exp(rng.normal(0, 0.25)))
    rgb = np.zeros((H * W, 3))
    rgb[idx] = lin
    rgb = rgb.reshape(H, W, 3)
    m = hit.reshape(H, W)
    # matting-like alpha
    if rng.random() < 0.6:
        alpha = gaussian_filter(alpha, rng.uniform(0.3, 1.2))
    if rng.random() < 0.3:
        c = rng.uniform(-0.3, 0.3)
        alpha = np.clip((alpha - 0.5) * rng.uniform(1.0, 2.0) + 0.5 - c, 0, 1)
    edge = (alpha > 0) & ~m
    if edge.any():
        _, (iy, ix) = distance_transform_edt(~m, return_indices=True)
        rgb[edge] = rgb[iy[edge], ix[edge]]
    return rgb, alpha, m, height.reshape(H, W)


def degrade(srgb8, rng):
    """Photo degradations (module doc) of a (H, W, 3) uint8 sRGB image."""
    from scipy.ndimage import gaussian_filter
    x = srgb8.astype(np.float32) / 255
    ops = []
    if rng.random() < 0.3:
        s = rng.uniform(0.3, 1.2)
        x = gaussian_filter(x, (s, s, 0))
        ops.append(f"blur{s:.2f}")
    sn = rng.uniform(0, 0.03)
    x = x + rng.normal(0, sn, x.shape)
    ops.append(f"noise{sn:.3f}")
    out = np.clip(np.round(x * 255), 0, 255).astype(np.uint8)
    if rng.random() < 0.6:
        from PIL import Image
        q = int(rng.integers(40, 96))
        buf = io.BytesIO()
        Image.fromarray(out).save(buf, "JPEG", quality=q)
        out = np.asarray(Image.open(io.BytesIO(buf.getvalue())).convert("RGB"))
        ops.append(f"jpeg{q}")
    return out, ops


def make_real_sample(split: str, index: int, seed: int = 0, res: int = 256, mix: str = "real",
                     category: str | None = None):
    """One sample (arrays, meta). ``mix``: ``real`` (the fourth model's categories, module doc)
    or ``real_organic`` (the same plus 20 % ``organic``). ``category``: only that procedural
    category (train/val only; its own random stream ``[seed, 13, split, index, category
    number]``, so organic-only samples are not copies of mixed ones)."""
    from pixgraph_lab.datagen.categories import CATEGORIES, make_object
    from pixgraph_nodes.ops.camera import Camera
    if mix not in ("real", "real_organic"):
        raise ValueError(f"unknown mix {mix!r}; known: real, real_organic")
    if category is not None:
        if category not in CATEGORIES:
            raise ValueError(f"unknown category {category!r}; known: {', '.join(CATEGORIES)}")
        if split == "test":
            raise ValueError("the test split is the named meshes only; --category is for train/val")
        rng = np.random.default_rng([seed, 13, SPLIT_CODE[split], index, CATEGORIES.index(category)])
    else:
        rng = np.random.default_rng([seed, 11, SPLIT_CODE[split], index])
    t0 = time.perf_counter()
    cat_p = CATEGORY_P if mix == "real_organic" else CATEGORY_P_REAL
    cats = list(cat_p)
    for tries in range(1, 200):
        kind, slots, names = None, None, ["body"]
        if split == "test":
            obj = list(NAMED)[rng.integers(len(NAMED))]
            V0, F = named_mesh(obj)
            category_ = obj
        elif category is not None:
            V0, F, slots, names, kind = make_object(category, rng)
            obj, category_ = kind, category
        elif rng.random() < 0.15:
            urdfs, procs = object_pool(split)
            obj = urdfs[rng.integers(len(urdfs))] if rng.random() >= 0.3 else procs[rng.integers(len(procs))]
            try:
                V0, F = raw_object(obj, rng)
            except ValueError:
                continue
            category_ = "v2"
        else:
            category_ = str(rng.choice(cats, p=list(cat_p.values())))
            V0, F, slots, names, kind = make_object(category_, rng)
            obj = kind
        if slots is None:
            slots = np.zeros(len(F), np.int64)
        pose = str(rng.choice(REAL_POSES, p=ORGANIC_POSE_P if category_ == "organic" else REAL_POSE_P))
        V = pose_real(V0, pose, rng)
        cam = Camera(res, res, hfov=float(rng.uniform(30, 70)), horizon=0.0,
                     cam_height=float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))))
        placed = _place(cam, V, rng)
        if placed is None:
            continue
        cam, PV = placed
        rgb, alpha, mask, height = render_real(cam, PV, F, slots, names, rng)
        if mask.sum() < 0.004 * res * res or (alpha[0] > 0).any() or (alpha[-1] > 0).any() \
                or (alpha[:, 0] > 0).any() or (alpha[:, -1] > 0).any():
            continue
        srgb8, ops = degrade(np.round(srgb_encode(rgb) * 255).astype(np.uint8), rng)
        meta = {"split": split, "index": index, "rng": [seed, 11, SPLIT_CODE[split], index], "mix": "real",
                "object": obj, "category": category_, "pose": pose, "overhang": is_overhang(mask, height),
                "camera": cam.to_dict(), "object_height": float(V[:, 1].max()), "degradations": ops,
                "mask_px": int(mask.sum()), "tries": tries, "seconds": time.perf_counter() - t0}
        arrays = {"rgb": srgb8, "alpha": np.round(alpha * 255).astype(np.uint8), "mask": mask,
                  "height": height.astype(np.float16)}
        return arrays, meta
    raise RuntimeError(f"sample {index}: no valid scene in 200 tries")


