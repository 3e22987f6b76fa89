"""Which occluder thickness should the example graphs use? Measured on real cutouts.

The shadow tracers treat a cutout as a shell ``thickness`` pixels deep behind its
pixel-height surface: too thin and rays slip through between samples (holes, a
shadow with gaps), too thick and the object is a wall reaching far behind itself
(shadows too long or too wide). We render generated scenes (lab/datagen: pybullet
random_urdfs meshes and procedural figures in front of walls, Mitsuba ray casts,
never-trained-on ``test`` split) and compare our hard shadow from the light's centre
with the renderer's, and our 32-sample soft shadow with the renderer's soft shadow,
for each thickness, using the true cutout heights and the contact-line heuristic
(what the example graphs use). Thickness is in pixels at the render's size; we
measure two sizes to see how it scales.

For reflections, the marched mirror on the floor against the exact planar mirror
(closed form) of the same cutout: holes (rays slipping through) against extra
pixels (the object reaching too far behind itself).

    python -m pixgraph_lab.thickness_study --n 24 --res 128 256 [--reflection]
"""
from __future__ import annotations

import argparse
import os
import tempfile

import numpy as np

THICKNESSES = (0.5, 1.0, 2.0, 4.0, 6.0, 8.0, 16.0, 32.0)


def study(device, data_dir: str, thicknesses=THICKNESSES) -> dict:
    from pixgraph_nodes.ops.heightmaps import contact_line_height
    from pixgraph_nodes.ops.lights import disk_samples
    from pixgraph_nodes.ops.shadow import hard_shadow, soft_shadow

    from .datagen.checks import iou, light_of
    from .datagen.dataset import load_sample, sample_files

    rows = {(h, t): {"iou": [], "rmse": []} for h in ("true", "contact_line") for t in thicknesses}
    for f in sample_files(data_dir):
        s = load_sample(f)
        cam, light = s["camera"], light_of(s)
        valid = ~s["mask"] & s["bg_valid"]
        mask = s["mask"].astype(np.float32)
        ref_hard = s["hard_shadow"] > 0.5
        ref_soft = s["shadow"].astype(np.float64)
        from pixgraph_nodes.ops.lights import light_point
        L, samples = light_point(light, cam), disk_samples(light, cam, 32)
        heights = {"true": s["fg_height"].astype(np.float32), "contact_line": contact_line_height(mask)}
        for hname, fg in heights.items():
            for t in thicknesses:
                hard = hard_shadow(device, mask, fg, s["bg_height"], L, t) < 0.5
                soft = 1.0 - soft_shadow(device, mask, fg, s["bg_height"], samples, t)
                rows[(hname, t)]["iou"].append(iou(hard, ref_hard, valid))
                rows[(hname, t)]["rmse"].append(float(np.sqrt(np.mean((soft - ref_soft)[valid] ** 2))))
    return {k: {m: float(np.mean(v)) for m, v in d.items()} | {"n": len(d["iou"])} for k, d in rows.items()}


def reflection_study(device, data_dir: str, thicknesses=THICKNESSES) -> dict:
    """Mirror reflection on the floor marched with each thickness against the exact
    planar mirror (``reflection_cl(planar=True)``, the closed form on flat ground)
    of the same cutout and true heights: the fraction of the exact reflection's
    pixels the march misses (holes) and of the marched pixels the exact one does not
    have (extra: the object reaching too far behind itself), on floor receivers."""
    from pixgraph_nodes.ops.reflection import reflection_cl

    from .datagen.dataset import load_sample, sample_files

    rows = {t: {"holes": [], "extra": []} for t in thicknesses}
    for f in sample_files(data_dir):
        s = load_sample(f)
        cam = s["camera"]
        a = s["alpha"].astype(np.float32)
        cut = np.concatenate([np.repeat(a[:, :, None], 3, axis=2) * 0.5, a[:, :, None]], axis=2)
        fg, bg = s["fg_height"].astype(np.float32), s["bg_height"].astype(np.float32)
        floor = (bg <= 0.5) & (a == 0)
        mirror = dict(roughness=0.0, conductor=True, f0=(1.0, 1.0, 1.0))   # full reflectance: alpha is coverage
        exact = reflection_cl(device, cam, cut, fg, bg, planar=True, **mirror)["layer"][..., 3] > 0.5
        exact &= floor
        if exact.sum() < 20:
            continue
        for t in thicknesses:
            marched = reflection_cl(device, cam, cut, fg, bg, planar=False, thickness=t,
                                    **mirror)["layer"][..., 3] > 0.5
            marched &= floor
            rows[t]["holes"].append(float((exact & ~marched).sum() / exact.sum()))
            rows[t]["extra"].append(float((marched & ~exact).sum() / exact.sum()))
    return {t: {m: float(np.mean(v)) for m, v in d.items()} | {"n": len(d["holes"])} for t, d in rows.items()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=24)
    ap.add_argument("--res", type=int, nargs="+", default=[128, 256])
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--data", default=None, help="folder for the generated samples (default: a temp folder)")
    ap.add_argument("--reflection", action="store_true", help="also the mirror reflection's thickness")
    args = ap.parse_args(argv)
    from pixgraph.device import Device

    from .datagen import generate

    device = Device.open()
    root = args.data or tempfile.mkdtemp(prefix="thickness-")
    for res in args.res:
        out = os.path.join(root, f"wall-{res}")
        if not os.path.exists(os.path.join(out, "index.json")):
            generate.main(["--benchmark", "wall", "--split", "test", "--n", str(args.n), "--seed", str(args.seed),
                           "--out", out, "--res", str(res), "--light-samples", "64", "--no-progress"])
        r = study(device, out)
        print(f"\nres {res}x{res}, {args.n} wall scenes (test split, seed {args.seed})")
        print("thickness_px  hardIoU_true  softRMSE_true  hardIoU_contact  softRMSE_contact")
        for t in THICKNESSES:
            a, b = r[("true", t)], r[("contact_line", t)]
            print(f"{t:12.1f}  {a['iou']:12.4f}  {a['rmse']:13.4f}  {b['iou']:15.4f}  {b['rmse']:16.4f}")
        if args.reflection:
            rr = reflection_study(device, out)
            print(f"mirror reflection on the floor, marched vs exact planar ({rr[THICKNESSES[0]]['n']} scenes)")
            print("thickness_px  holes  extra")
            for t in THICKNESSES:
                print(f"{t:12.1f}  {rr[t]['holes']:.4f}  {rr[t]['extra']:.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
