"""Checks of generated ground truth (no Mitsuba needed; the tracer check needs OpenCL).

    python -m pixgraph_lab.datagen.checks --data data/wall_test [--limit 100] [--thickness 1 4 16]

1. **Reconstruction**: the stored pixel heights fed to ``camera.reconstruct`` must
   give back the 3D points the camera rays hit. The true point of pixel (u, v) is
   ``O' + (D / f) (u - W/2, horizon - v, -f)`` with the stored depth D (world
   units), so the error is that of the pixel-height parametrisation plus float32
   storage. Reported as max and mean |P_rec - P_true| (world units, camera height
   = 1) and relative to the depth, over the cutout and over the background.
2. **Hard shadow vs. our tracer**: IoU of the renderer's hard shadow (one shadow
   ray per pixel to the light's centre, against the 3D mesh) and the pixel-height
   hard shadow (``nodes/ops/shadow.hard_shadow``) on the same light point, over
   background pixels outside the cutout, per background kind and per tracer
   ``thickness``. They differ where the pixel-height model is wrong, not the
   tracer: surfaces hidden from the camera (the back of the object casts shadow in
   3D but has no pixel height), thickness (a ray passing behind the visible
   surface), and thin parts aliased by one ray per pixel.
"""
from __future__ import annotations

import argparse
import collections

import numpy as np

from pixgraph_nodes.ops.camera import reconstruct

from .dataset import load_sample, sample_files


def true_points(camera, depth):
    """World points (H, W, 3) of every pixel's camera ray at depth D = -Z (world units)."""
    u, v = camera.pixel_grid()
    w = depth / camera.focal
    return np.stack([w * (u - camera.width / 2.0), camera.cam_height + w * (camera.horizon - v),
                     -camera.focal * w], axis=-1)


def reconstruction_errors(sample: dict) -> dict:
    """Max / mean point error of reconstruct() on the cutout and the background."""
    cam = sample["camera"]
    out = {}
    for part, hkey, dkey, sel in (("cutout", "fg_height", "fg_depth", sample["mask"]),
                                  ("background", "bg_height", "bg_depth", sample["bg_valid"])):
        rec = reconstruct(cam, sample[hkey])
        P = true_points(cam, sample[dkey].astype(np.float64))
        ok = sel & (rec["valid"] > 0)
        if not ok.any():
            continue
        err = np.linalg.norm(rec["position"].astype(np.float64) - P, axis=-1)[ok]
        rel = err / sample[dkey][ok]
        out[part] = {"max": float(err.max()), "mean": float(err.mean()), "rel_max": float(rel.max()),
                     "rel_mean": float(rel.mean()), "pixels": int(ok.sum()),
                     "invalid": int((sel & ~(rec["valid"] > 0)).sum())}
    return out


def light_of(sample: dict):
    """The sample's disk light as a ``nodes/ops/lights.Light``."""
    from pixgraph_nodes.ops.lights import Light
    return Light("disk", position=tuple(float(x) for x in sample["light_center"]),
                 radius=float(sample["light_radius"]),
                 normal=tuple(float(x) for x in sample["light_normal"]))


def tracer_hard_darkness(device, sample: dict, thickness: float = 1.0) -> np.ndarray:
    """Our pixel-height hard shadow from the light's centre, as darkness (1 = shadow)."""
    from pixgraph_nodes.ops.lights import light_point
    from pixgraph_nodes.ops.shadow import hard_shadow
    L = light_point(light_of(sample), sample["camera"])
    lit = hard_shadow(device, sample["mask"].astype(np.float32), sample["fg_height"], sample["bg_height"],
                      L, thickness)
    return 1.0 - lit


def iou(a: np.ndarray, b: np.ndarray, valid: np.ndarray) -> float:
    a, b = a & valid, b & valid
    union = (a | b).sum()
    return float((a & b).sum() / union) if union else 1.0


def explain_disagreement(files, device, thickness: float = 1.0) -> list[str]:
    """Classify the pixels where the renderer's hard shadow and our tracer's differ.

    renderer-only pixels (3D shadow the tracer misses): the shadow ray from the
    receiver to the light's centre is followed through every object surface it
    crosses; when none of those crossing points is visible from the camera (no
    pixel shows that point at that depth, within 2 % in a 3x3 neighbourhood) the
    occluder is **hidden** (back faces, parts behind other parts) — information
    pixel height cannot have. Otherwise the pixel is a *seen-occluder* miss
    (thickness too small, discretisation of the march, silhouette pixels).
    tracer-only pixels are shadow the 3D object does not cast: the ray passes
    behind the visible surface where the real object is thinner than the
    ``thickness`` band (or at the silhouette). Needs Mitsuba (re-casts the scene).
    """
    from .generate import make_sample
    tot = collections.Counter()
    for f in files:
        s = load_sample(f)
        m = s["meta"]
        arrays, _, rend, light = make_sample(m["benchmark"], m["split"], m["index"], m["rng"][0],
                                             s["shadow"].shape[0], 1, return_scene=True)
        if not np.array_equal(arrays["hard_shadow"], s["hard_shadow"]):
            raise RuntimeError(f"{f}: regenerated scene differs from the stored one")
        cam = s["camera"]
        valid = ~s["mask"] & s["bg_valid"]
        ref = s["hard_shadow"] > 0
        ours = tracer_hard_darkness(device, s, thickness) > 0.5
        ref_only = np.nonzero((ref & ~ours & valid).ravel())[0]
        tot["ref_px"] += int((ref & valid).sum())
        tot["both"] += int((ref & ours & valid).sum())
        tot["tracer_only"] += int((ours & ~ref & valid).sum())
        tot["renderer_only"] += len(ref_only)
        if not len(ref_only):
            continue
        pr = rend.primary()
        P = pr["bg_points"][ref_only] + pr["bg_normals"][ref_only] * 1e-4
        w = light.center - P
        dist = np.linalg.norm(w, axis=1)
        w /= dist[:, None]
        seen = np.zeros(len(P), bool)
        o, left = P.copy(), dist.copy()
        H, W = cam.height, cam.width
        for _ in range(12):                      # walk through successive surface crossings
            t, X, _ = rend.obj.intersect(o, w, left)
            hit = np.isfinite(t) & (t < left)
            if not hit.any():
                break
            uvh, D = cam.project(X[hit])
            iu, iv = np.floor(uvh[:, 0]).astype(int), np.floor(uvh[:, 1]).astype(int)
            vis = np.zeros(hit.sum(), bool)
            for dv in (-1, 0, 1):
                for du in (-1, 0, 1):
                    u2, v2 = iu + du, iv + dv
                    ok = (u2 >= 0) & (u2 < W) & (v2 >= 0) & (v2 < H)
                    u2, v2 = np.clip(u2, 0, W - 1), np.clip(v2, 0, H - 1)
                    vis |= ok & s["mask"][v2, u2] & (np.abs(s["fg_depth"][v2, u2] - D) < 0.02 * D)
            idx = np.nonzero(hit)[0]
            seen[idx[vis]] = True
            o[hit] = X[hit] + w[hit] * 1e-4
            left = np.where(hit, left - t - 1e-4, 0.0)
        tot["renderer_only_hidden"] += int((~seen).sum())
        tot["renderer_only_seen"] += int(seen.sum())
    ro = max(1, tot["renderer_only"])
    return [f"hard-shadow disagreement over {len(files)} samples, thickness {thickness:g} px: "
            f"{tot['ref_px']} renderer shadow px, {tot['both']} shared; renderer-only {tot['renderer_only']} "
            f"({tot['renderer_only_hidden'] / ro:.0%} with the occluder hidden from the camera, "
            f"{tot['renderer_only_seen'] / ro:.0%} seen); tracer-only {tot['tracer_only']}"]


def noise_floor(files) -> list[str]:
    """Render each sample's soft shadow again with independent light samples and
    compare: metrics(render2, render1) is what a perfect method would score
    against this ground truth (two noisy copies; RMSE between them / sqrt(2) is
    the noise of one)."""
    from ..metrics import shadow_metrics
    from .generate import make_sample
    rows = []
    for f in files:
        s = load_sample(f)
        c = s["meta"]["index"]
        cfg = s["meta"]
        arrays, _ = make_sample(cfg["benchmark"], cfg["split"], c, cfg["rng"][0], s["shadow"].shape[0],
                                int(s["light_samples"]), soft_rng=np.random.default_rng([12345, c]))
        if not np.array_equal(arrays["hard_shadow"], s["hard_shadow"]):
            raise RuntimeError(f"{f}: regenerated scene differs from the stored one")
        valid = ~s["mask"] & s["bg_valid"]
        rows.append(shadow_metrics(arrays["shadow"], s["shadow"], valid))
    m = {k: float(np.mean([r[k] for r in rows])) for k in rows[0]}
    return [f"noise floor over {len(rows)} samples (second render vs stored): RMSE {m['rmse']:.4f} "
            f"(one render: {m['rmse'] / np.sqrt(2):.4f}), RMSE-s {m['rmse_s']:.4f}, SSIM {m['ssim']:.4f}, "
            f"ZNCC {m['zncc']:.4f}"]


def dataset_summary(metas) -> list[str]:
    """Lines describing a benchmark from its per-sample metadata: kinds, light
    ranges, Monte-Carlo noise and generation time."""
    st = [m["stats"] for m in metas]
    kinds = collections.Counter(m["scene"]["background"] for m in metas)
    objs = collections.Counter(m["scene"]["object"].split(":")[0] for m in metas)
    rel = np.array([m["light"]["relative_radius"] for m in metas])
    el = np.array([m["light"]["elevation_deg"] for m in metas])
    wall_frac = np.array([s["shadow_wall_px"] / max(1, s["shadow_px"]) for s in st])
    return [
        f"backgrounds {dict(kinds)}; objects {dict(objs)} ({len({m['scene']['object'] for m in metas})} distinct)",
        f"light radius/distance {rel.min():.3f}..{rel.max():.3f} (median {np.median(rel):.3f}); "
        f"elevation {el.min():.1f}..{el.max():.1f} deg; lights behind the camera "
        f"{sum(m['light_uvhs'][3] < 0 for m in metas)}",
        f"light samples/pixel {sorted({m['light_samples'] for m in metas})}; MC std error in the penumbra: "
        f"mean {np.mean([s['stderr_mean_penumbra'] for s in st]):.4f}, max pixel {max(s['stderr_max'] for s in st):.4f}",
        f"shadow pixels (darkness > 0.01) per sample: median {np.median([s['shadow_px'] for s in st]):.0f}; "
        f"fraction on walls: median {np.median(wall_frac):.2f}",
        f"time per sample: ray casting {np.mean([s['render_seconds'] for s in st]):.2f} s, total incl. rejected "
        f"scenes/lights {np.mean([s['total_seconds'] for s in st]):.2f} s; light tries mean "
        f"{np.mean([s['light_tries'] for s in st]):.1f}, scene tries mean {np.mean([s['scene_tries'] for s in st]):.2f}",
    ]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.datagen.checks", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True)
    ap.add_argument("--limit", type=int, default=0)
    ap.add_argument("--thickness", type=float, nargs="+", default=[1.0])
    ap.add_argument("--no-tracer", action="store_true", help="skip the OpenCL tracer comparison")
    ap.add_argument("--explain", type=int, default=0,
                    help="classify renderer/tracer hard-shadow differences on the first N samples (needs Mitsuba)")
    ap.add_argument("--noise", type=int, default=0,
                    help="re-render the soft shadow of the first N samples with independent light samples "
                         "(needs Mitsuba) and report the ground truth's own RMSE/SSIM noise floor")
    a = ap.parse_args(argv)
    files = sample_files(a.data)
    if a.limit:
        files = files[:a.limit]
    device = None
    if not a.no_tracer:
        from pixgraph.device import Device
        device = Device.open()
    rec = collections.defaultdict(list)
    ious = collections.defaultdict(list)
    for f in files:
        s = load_sample(f)
        for part, e in reconstruction_errors(s).items():
            rec[part].append(e)
        if device is not None:
            kind = s["meta"]["scene"]["background"]
            valid = ~s["mask"] & s["bg_valid"]
            ref = s["hard_shadow"] > 0
            for t in a.thickness:
                ours = tracer_hard_darkness(device, s, t) > 0.5
                ious[(kind, t)].append(iou(ours, ref, valid))
                ious[("all", t)].append(iou(ours, ref, valid))
    print(f"{len(files)} samples from {a.data}")
    for line in dataset_summary([load_sample(f)["meta"] for f in files]):
        print(line)
    print("reconstruction (world units; camera height = 1):")
    for part, es in rec.items():
        print(f"  {part:10s} max {max(e['max'] for e in es):.3e}  mean {np.mean([e['mean'] for e in es]):.3e}"
              f"  rel max {max(e['rel_max'] for e in es):.3e}  rel mean {np.mean([e['rel_mean'] for e in es]):.3e}"
              f"  invalid px {sum(e['invalid'] for e in es)}")
    if a.explain:
        for t in a.thickness:
            for line in explain_disagreement(files[:a.explain], device, t):
                print(line)
    if a.noise:
        for line in noise_floor(files[:a.noise]):
            print(line)
    if ious:
        print("hard shadow IoU, renderer vs pixel-height tracer (mean / median over samples):")
        print("  | background | thickness [px] | n | mean IoU | median IoU |")
        print("  |---|---|---|---|---|")
        for (kind, t), v in sorted(ious.items(), key=lambda kv: (kv[0][0] != "all", kv[0])):
            print(f"  | {kind} | {t:g} | {len(v)} | {np.mean(v):.3f} | {np.median(v):.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
