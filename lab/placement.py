"""Placement against the renderer: is a cutout placed at scale s and position p the
same as the scene rendered directly at that size?

One generated scene (lab/datagen: a random_urdfs object or a procedural shape in
front of walls, Mitsuba ray casts) is rendered twice with the same 3D content: at
``res`` (the cutout) and at ``round(res * s)`` (the canvas; the camera's focal
length and horizon scale with the image, so every pixel coordinate scales by s).
The small render's object, cropped to its bounding box plus a margin, is placed
with ``pixgraph_nodes.ops.placement.place_cutout`` at scale s, its foot at s times
its foot in the small render. We compare, on the canvas:

- the hard shadow our tracer casts from the light's centre with the direct render's
  mask and pixel heights, and with the placed ones (IoU over background pixels);
- the placed pixel heights against the direct render's (median absolute error
  inside the eroded mask, px) — the heights were scaled by s.

    python -m pixgraph_lab.placement --index 0 1 2 3 4 5 --res 256 --scale 1.5 0.5 [--solid]
"""
from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from pixgraph_nodes.ops.lights import Light, disk_samples, foot_of_mask, light_point
from pixgraph_nodes.ops.placement import place_cutout
from pixgraph_nodes.ops.shadow import hard_shadow, soft_shadow


def _render(spec, res: int, base_res: int):
    from .datagen.render import SampleRenderer

    cam = spec.camera
    k = res / base_res
    cam = dataclasses.replace(cam, width=res, height=res, horizon=cam.horizon * k)
    return SampleRenderer(dataclasses.replace(spec, camera=cam)).primary(subsamples=4), cam


def _solid_object(spec):
    """The scene with its object replaced by a solid one of the same height at the same
    base: a box yawed by 30 degrees with a smaller box on top (a step in its outline).
    Thin objects (a figure's limbs) have silhouettes one or two pixels wide, which no
    two samplings of the same scene agree on; a solid object measures the placement."""
    import trimesh

    ht = float(spec.obj_V[:, 1].max())
    lower = trimesh.creation.box(extents=[0.45 * ht, 0.6 * ht, 0.3 * ht])
    lower.apply_translation([0.0, 0.3 * ht, 0.0])
    upper = trimesh.creation.box(extents=[0.25 * ht, 0.4 * ht, 0.2 * ht])
    upper.apply_translation([0.08 * ht, 0.8 * ht, 0.0])
    m = trimesh.util.concatenate([lower, upper])
    m.apply_transform(trimesh.transformations.rotation_matrix(np.radians(30.0), [0, 1, 0]))
    V = np.asarray(m.vertices, float) + spec.base
    return dataclasses.replace(spec, obj_id="solid:box+box", obj_V=V, obj_F=np.asarray(m.faces))


def measure(device, index: int, res: int, scale: float, seed: int = 0, margin: int = 4,
            thickness: float = 6.0, solid: bool = False) -> dict:
    """Shadow IoU / RMSE and height error of one scene (see the module doc); ``solid``
    replaces the generated object by a solid one (``_solid_object``). ``thickness``
    [px] is the occluder thickness of both shadows: 6, the example graphs' value
    (lab/thickness_study.py); at 2 the tracer's holes in shadows of steep surfaces
    are striped, and the stripes move with sub-pixel height changes."""
    from .datagen.generate import make_sample

    _, _, rend, light = make_sample("wall", "test", index, seed=seed, res=res, light_samples=4,
                                    return_scene=True)
    spec = rend.spec
    if solid:
        spec = _solid_object(spec)
    canvas_res = int(round(res * scale))
    small, _ = _render(spec, res, res)
    big, cam = _render(spec, canvas_res, res)
    # the cutout: the small render's object, cropped (a user's cutout has its own size)
    a = small["alpha"].astype(np.float32)
    rows, cols = np.nonzero(a > 0)
    r0, r1 = max(0, rows.min() - margin), min(res, rows.max() + 1 + margin)
    c0, c1 = max(0, cols.min() - margin), min(res, cols.max() + 1 + margin)
    alpha = a[r0:r1, c0:c1]
    # the render has heights only where a pixel's centre sees the object; a cutout's
    # map covers its whole alpha: edge pixels take the nearest centre hit's height
    from scipy.ndimage import distance_transform_edt

    near = distance_transform_edt(~small["mask"], return_distances=False, return_indices=True)
    filled = np.where(small["alpha"] > 0, small["fg_height"][near[0], near[1]], 0.0)
    height = filled[r0:r1, c0:c1].astype(np.float32)
    colour = np.repeat(alpha[:, :, None], 3, axis=2) * 0.5
    rgba = np.concatenate([colour, alpha[:, :, None]], axis=2)
    ax, ay = foot_of_mask(alpha)
    foot = ((ax + c0) * scale, (ay + r0) * scale)            # p: where the foot is in the direct render
    _, p_alpha, p_height = place_cutout(rgba, alpha, height, (canvas_res, canvas_res), foot, scale)
    lt = Light("disk", position=tuple(map(float, light.center)), radius=float(light.radius),
               normal=tuple(map(float, light.normal)))
    L, samples = light_point(lt, cam), disk_samples(lt, cam, 64)
    bg_h = big["bg_height"].astype(np.float32)
    # the direct render's pixels that see the object at their centre carry its heights
    d_mask, d_h = big["mask"].astype(np.float32), big["fg_height"].astype(np.float32)
    free = ~(big["mask"] | (p_alpha > 0.5)) & big["bg_valid"]

    def iou(a, b):
        union = ((a | b) & free).sum()
        return float(((a & b) & free).sum() / union) if union else 1.0

    hard_iou = iou(hard_shadow(device, d_mask, d_h, bg_h, L, thickness) < 0.5,
                   hard_shadow(device, p_alpha, p_height, bg_h, L, thickness) < 0.5)
    d_soft = 1.0 - soft_shadow(device, d_mask, d_h, bg_h, samples, thickness)
    p_soft = 1.0 - soft_shadow(device, p_alpha, p_height, bg_h, samples, thickness)
    soft_iou = iou(d_soft > 0.5, p_soft > 0.5)
    # the noise floor: the same render, same size, its coverage (alpha > 0.5) as the
    # mask instead of the pixel-centre hits, heights from the nearest centre hit
    idx = distance_transform_edt(~big["mask"], return_distances=False, return_indices=True)
    f_mask = (big["alpha"] > 0.5).astype(np.float32)
    f_h = np.where(f_mask > 0, d_h[idx[0], idx[1]], 0.0).astype(np.float32)
    f_soft = 1.0 - soft_shadow(device, f_mask, f_h, bg_h, samples, thickness)
    floor_iou = iou(d_soft > 0.5, f_soft > 0.5)
    # like for like: the direct render made into a cutout the way the small one was
    # (coverage mask, nearest-centre heights) against the placed cutout
    cov_iou = iou(f_soft > 0.5, p_soft > 0.5)
    soft_rmse = float(np.sqrt(np.mean((d_soft - p_soft)[free] ** 2)))
    from scipy.ndimage import binary_erosion

    inner = binary_erosion(big["mask"] & (p_alpha > 0.99), iterations=2)
    herr = np.abs(p_height - big["fg_height"])[inner] if inner.any() else np.zeros(1)
    mask_iou = float(((big["alpha"] > 0.5) & (p_alpha > 0.5)).sum() / ((big["alpha"] > 0.5) | (p_alpha > 0.5)).sum())
    return {"index": index, "object": spec.obj_id, "background": spec.bg_kind, "res": res, "scale": scale,
            "canvas": canvas_res, "cutout": [int(c1 - c0), int(r1 - r0)], "foot": [float(foot[0]), float(foot[1])],
            "soft_iou": soft_iou, "floor_iou": floor_iou, "cov_iou": cov_iou, "hard_iou": hard_iou, "soft_rmse": soft_rmse, "mask_iou": mask_iou,
            "height_median_abs_px": float(np.median(herr)), "height_max_px": float(big["fg_height"].max()),
            "height_ratio": float(np.percentile(p_height[p_alpha > 0.5], 90) / np.percentile(height[alpha > 0.5], 90))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--index", type=int, nargs="+", default=[0, 1, 2])
    ap.add_argument("--res", type=int, default=96)
    ap.add_argument("--scale", type=float, nargs="+", default=[1.5, 0.5])
    ap.add_argument("--solid", action="store_true", help="a solid object instead of the generated one")
    ap.add_argument("--thickness", type=float, default=6.0, help="occluder thickness of the shadows [px]")
    args = ap.parse_args(argv)
    from pixgraph.device import Device

    device = Device.open()
    print("index object                          bg            scale canvas cutout   soft_IoU floor_IoU  cov_IoU hard_IoU "
          "soft_RMSE mask_IoU |dh| med px  max h px")
    for i in args.index:
        for s in args.scale:
            r = measure(device, i, args.res, s, solid=args.solid, thickness=args.thickness)
            print(f"{i:5d} {r['object'][:31]:31s} {r['background']:13s} {s:5.2f} {r['canvas']:6d} "
                  f"{r['cutout'][0]:3d}x{r['cutout'][1]:<4d} {r['soft_iou']:8.4f} {r['floor_iou']:9.4f} {r['cov_iou']:8.4f} {r['hard_iou']:8.4f} {r['soft_rmse']:9.4f} {r['mask_iou']:8.4f} "
                  f"{r['height_median_abs_px']:11.3f} {r['height_max_px']:9.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
