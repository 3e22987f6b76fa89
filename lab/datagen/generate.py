"""Generate a ground-truth benchmark reproducibly from a seed.

    python -m pixgraph_lab.datagen.generate --benchmark wall --split test --n 500 --seed 0 --out data/wall_test

Sample ``i`` depends only on ``(seed, benchmark, split, i)`` (numpy's
``default_rng([seed, bench, split, i])``), so runs are resumable: existing
``NNNNN.npz`` files are skipped, and any subset can be regenerated alone. The
index ``index.json`` (config + one metadata record per sample) is rewritten every
few samples and at the end.

Benchmarks (the paper's Sec. 4): ``ground`` — the background is the ground plane
only; ``wall`` — a wall template (scene.WALL_KINDS_*) and a light whose hard
shadow puts at least ``min_wall_px`` visible pixels on a non-ground surface
(lights are re-drawn until it does, up to 40 times, then the scene is re-drawn).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time

import numpy as np

from .dataset import FORMAT_VERSION, sample_path, save_sample
from .objects import choose_object, load_object
from .scene import (WALL_KINDS_TEST, WALL_KINDS_TRAIN, SceneSpec, make_camera, place_object,
                    sample_background_params, sample_light)

BENCH_CODE = {"ground": 1, "wall": 2}
SPLIT_CODE = {"train": 1, "test": 2}


def sample_rng(seed: int, benchmark: str, split: str, index: int) -> np.random.Generator:
    return np.random.default_rng([seed, BENCH_CODE[benchmark], SPLIT_CODE[split], index])


def make_sample(benchmark: str, split: str, index: int, seed: int = 0, res: int = 256,
                light_samples: int = 256, min_shadow_frac: float = 0.002, soft_rng=None,
                return_scene: bool = False, mix: int = 1):
    """Build and ray-cast one sample. Returns ``(arrays, meta)``.

    min_shadow_frac: the visible hard shadow (and for ``wall`` its part on walls)
    must cover at least this fraction of the image (0.2 % = 131 px at 256^2).
    soft_rng: a separate generator for the soft shadow's light samples only (the
    scene stays the same); used to measure the Monte-Carlo noise by rendering a
    sample twice (checks.py --noise).
    return_scene: also return the ``SampleRenderer`` and ``DiskLight`` (for checks
    that cast more rays into the same scene).
    mix: the object mix (``objects.choose_object``): 1 = the generator's first
    objects (meshes + solid procedural shapes), 2 = also thin open objects (tables,
    chairs, frames in train; arches, benches in test) a quarter of the time.
    """
    from .render import SampleRenderer, render
    rng = sample_rng(seed, benchmark, split, index)
    t0 = time.perf_counter()
    kinds = ("ground",) if benchmark == "ground" else (WALL_KINDS_TEST if split == "test" else WALL_KINDS_TRAIN)
    min_px = max(4, int(round(min_shadow_frac * res * res)))
    scene_tries = light_tries = 0
    while True:
        scene_tries += 1
        if scene_tries > 200:
            raise RuntimeError(f"sample {index}: no valid scene in 200 tries")
        obj_id = choose_object(split, rng, mix=mix)
        try:
            V, F = load_object(obj_id, rng)
        except ValueError:          # broken source mesh: draw another object
            continue
        placed = place_object(make_camera(res, rng), V, rng)
        if placed is None:
            continue
        cam, PV, base = placed
        kind = str(kinds[rng.integers(len(kinds))])
        r_foot = float(np.hypot(V[:, 0], V[:, 2]).max())
        params = sample_background_params(kind, split, rng, r_foot)
        spec = SceneSpec(cam, obj_id, PV, F, kind, params, base)
        rend = SampleRenderer(spec)
        pr = rend.primary()
        m = pr["mask"]
        # the cutout must be whole (not cut by the border, not hidden by the background)
        if m.sum() < 0.005 * res * res or m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any():
            continue
        for _ in range(40):
            light_tries += 1
            light = sample_light(spec, rng)
            if not rend.light_ok(light):
                continue
            hard = rend.hard_shadow(light).astype(bool) & ~m
            wall_px = int((hard & ~pr["bg_is_ground"]).sum())
            if hard.sum() < min_px or (benchmark == "wall" and wall_px < min_px):
                continue
            albedo = rng.uniform(0.2, 0.9, 3)
            arrays = render(spec, light, light_samples, rng if soft_rng is None else soft_rng,
                            renderer=rend, albedo=albedo)
            shadow, err = arrays["shadow"], arrays["shadow_stderr"].astype(np.float32)
            pen = (shadow > 0.01) & (shadow < 0.99) & ~m
            meta = {
                "format": FORMAT_VERSION, "benchmark": benchmark, "split": split, "index": index, "mix": mix,
                "rng": [seed, BENCH_CODE[benchmark], SPLIT_CODE[split], index],
                "scene": spec.to_json(), "light": light.to_json(),
                "light_uvhs": [float(x) for x in arrays["light_uvhs"]], "albedo": [float(a) for a in albedo],
                "light_samples": int(arrays["light_samples"]),
                "stats": {"mask_px": int(m.sum()), "hard_shadow_px": int(hard.sum()),
                          "hard_shadow_wall_px": wall_px,
                          "shadow_px": int(((shadow > 0.01) & ~m).sum()),
                          "shadow_wall_px": int(((shadow > 0.01) & ~m & ~pr["bg_is_ground"]).sum()),
                          "stderr_mean_penumbra": float(err[pen].mean()) if pen.any() else 0.0,
                          "stderr_max": float(err.max()),
                          "scene_tries": scene_tries, "light_tries": light_tries,
                          "render_seconds": float(arrays["render_seconds"]),
                          "total_seconds": float(time.perf_counter() - t0)},
            }
            if return_scene:
                return arrays, meta, rend, light
            return arrays, meta
        # no light worked for this scene: draw a new scene


def write_index(out: str, config: dict, n: int) -> dict:
    metas = []
    for i in range(config["start"], config["start"] + n):
        p = sample_path(out, i)
        if os.path.exists(p):
            with np.load(p) as z:
                metas.append(json.loads(str(z["meta"])))
    index = {"format": FORMAT_VERSION, "config": config, "count": len(metas), "samples": metas}
    # one temp file per process: shards (--start) of one folder run side by side
    tmp = os.path.join(out, f"index.json.{os.getpid()}.tmp")
    with open(tmp, "w") as fh:
        json.dump(index, fh, indent=1)
    os.replace(tmp, os.path.join(out, "index.json"))
    return index


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.datagen.generate", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--benchmark", choices=sorted(BENCH_CODE), required=True)
    ap.add_argument("--split", choices=sorted(SPLIT_CODE), required=True)
    ap.add_argument("--n", type=int, required=True, help="number of samples")
    ap.add_argument("--start", type=int, default=0, help="first sample index (for sharding)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", required=True)
    ap.add_argument("--res", type=int, default=256, help="image size in pixels (square)")
    ap.add_argument("--light-samples", type=int, default=256,
                    help="disk-light samples per pixel for the soft shadow (rounded up to k*k)")
    ap.add_argument("--mix", type=int, choices=(1, 2), default=1,
                    help="object mix: 1 = meshes + solid shapes (the first benchmarks), "
                         "2 = also thin open objects (tables, chairs, frames / arches, benches)")
    ap.add_argument("--no-progress", action="store_true")
    a = ap.parse_args(argv)
    from tqdm import tqdm

    from .raycast import select_variant
    variant = select_variant()
    os.makedirs(a.out, exist_ok=True)
    config = {"benchmark": a.benchmark, "split": a.split, "n": a.n, "start": a.start, "seed": a.seed,
              "res": a.res, "light_samples": a.light_samples, "mix": a.mix, "mitsuba_variant": variant,
              "command": " ".join(["python -m pixgraph_lab.datagen.generate"] + (argv or sys.argv[1:])),
              "host": platform.node()}
    t0 = time.perf_counter()
    made = 0
    for k, i in enumerate(tqdm(range(a.start, a.start + a.n), desc=f"{a.benchmark}/{a.split}",
                               disable=a.no_progress)):
        p = sample_path(a.out, i)
        if os.path.exists(p):
            continue
        arrays, meta = make_sample(a.benchmark, a.split, i, a.seed, a.res, a.light_samples, mix=a.mix)
        save_sample(p, arrays, meta)
        made += 1
        if made % 25 == 0:
            write_index(a.out, config, a.n)
    dt = time.perf_counter() - t0
    index = write_index(a.out, config, a.n)
    rate = made / dt if dt > 0 else 0.0
    print(f"{made} new samples in {dt:.1f} s ({rate:.3f} samples/s, {dt / max(made, 1):.2f} s/sample, "
          f"variant {variant}); {index['count']}/{a.n} present in {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
