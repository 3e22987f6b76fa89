"""Reflection benchmark: speed against accuracy (PixHt-Lab Sec. 3.3: ~7 s for a
noise-free 512x512 glossy reflection at 200 spp on a CUDA GPU).

    python benchmarks/reflection_bench.py            # full run, a few minutes
    python benchmarks/reflection_bench.py --quick    # fewer points, one repeat
    python benchmarks/reflection_bench.py --proxy-errors --size 1280 --size 20mp   # the proxies' error
    python benchmarks/reflection_bench.py --proxy-errors --size 1280 --seed-floor  # + the sampling noise

``--proxy-errors``: the error of Reflection's and Refraction's ``proxy`` against the
full computation (``proxy: 0``) on the photo of benchmarks/photo_bench.py at each
``--size`` (``20mp`` = 5120x3840, ``1280`` = 1280x960, ``512`` = 512x384): the glossy
floor of its ``glossy`` case (roughness 0.2, receivers ground) and a glass ball
(pixgraph.Sphere, eta 1.5, local-sphere back surface) on the same photo. RMSE and
max |error| of the premultiplied linear RGBA layer over the affected pixels: for
the reflection those where either layer is not 0, outside the cutout (what is
seen); for the refraction the glass's pixels (alpha > 0), and its interior (6 px
and more inside the outline). Node times are medians of ``--repeat`` runs (the
full computation: one run); the full layers are kept under out/bench/photo/.

Scene: the example figure (graphs/assets/figure.png) moved up 150 rows so its
whole reflection lies in the image, contact-line pixel height, flat ground,
camera 512x512, hfov 50, horizon 120. Two floors, both roughness 0.2:
``dielectric`` (eta 1.5, exact Fresnel; the glossy_floor.yaml setting) and
``metal`` (conductor, f0 0.9: a bright reflection, the harder case).

Accuracy: RMSE over all pixels and RGBA channels of the premultiplied layer
against our own reference, cached under out/bench/: up to 4096 samples per pixel,
adaptive with a 1e-4 standard-error target after 256 samples (pixels whose
first 256 low-discrepancy samples all miss the cutout are taken as 0).

Timings: wall-clock of ``reflection_cl`` (host set-up, upload, kernels, download),
median of ``--repeat`` runs. Prints machine, OpenCL device and load average:
the machine is shared, so timings carry that noise.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import pathlib
import platform
import statistics
import sys
import time

import numpy as np

from pixgraph.device import Device
from pixgraph_nodes.ops import reflection as R
from pixgraph_nodes.ops.camera import Camera
from pixgraph_nodes.ops.heightmaps import ContactLinePredictor
from pixgraph_nodes.ops.imageio import read_image

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "out" / "bench"
CHART = ROOT / "docs" / "img" / "reflection_speed_accuracy.png"
MATERIALS = {
    "dielectric": dict(roughness=0.2, eta=1.5, conductor=False),
    "metal": dict(roughness=0.2, conductor=True, f0=(0.9, 0.9, 0.9)),
}
TARGET_RMSE = 0.005


def scene():
    img, _ = read_image(ROOT / "graphs" / "assets" / "figure.png")
    cut = np.roll(img, -150, axis=0)
    cut[-150:] = 0.0
    fg = ContactLinePredictor("contact_line", 2.0).predict(cut)
    cam = Camera(512, 512, hfov=50.0, horizon=120.0)
    return cam, np.ascontiguousarray(cut, np.float32), fg, np.zeros((512, 512), np.float32)


def timed(fn, repeat):
    ts, out = [], None
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t)
    return statistics.median(ts), ts, out


def rmse(a, b):
    return float(np.sqrt(np.mean((a.astype(np.float64) - b) ** 2)))


def reference(dev, sc, name, mat):
    cam, cut, fg, bg = sc
    key = hashlib.sha256(cut.tobytes() + fg.tobytes() + json.dumps(mat, sort_keys=True).encode()).hexdigest()[:16]
    path = OUT / f"reflection_ref_{name}_{key}.npy"
    if path.exists():
        return np.load(path), None
    t = time.perf_counter()
    r = R.reflection_cl(dev, cam, cut, fg, bg, min_spp=256, max_spp=4096, target_se=1e-4, seed=1000003,
                        progress=lambda f, m: print(f"  reference {name}: {f:4.0%}", flush=True), **mat)
    dt = time.perf_counter() - t
    OUT.mkdir(parents=True, exist_ok=True)
    np.save(path, r["layer"])
    print(f"  reference {name}: {dt:.1f} s, mean spp {r['spp'].mean():.1f}, "
          f"{(r['spp'] == 4096).mean():.1%} pixels at 4096")
    return r["layer"], dt


REFRACTION = """pixgraph: 1
nodes:
  photo: {{type: pixgraph.LoadImage, params: {{path: {photo}}}}}
  cam:   {{type: pixgraph.Camera, inputs: {{image: photo.image}}, params: {{horizon: {horizon}}}}}
  bg_h:
    type: pixgraph.BackgroundHeight
    inputs: {{camera: cam.camera}}
    params: {{kind: back_wall, junction_points: [0, {j0}, {width}, {j1}]}}
  ball:
    type: pixgraph.Sphere
    inputs: {{camera: cam.camera}}
    params: {{center_u: {cu}, contact_v: {cv}, radius: 0.12}}
  refr:
    type: pixgraph.Refraction
    inputs: {{camera: cam.camera, glass: ball.image, glass_height: ball.height,
             background: photo.image, bg_height: bg_h.height}}
    params: {{eta: 1.5, fresnel: true, back_surface: local_sphere}}
outputs: {{refraction: refr.layer}}
"""


def proxy_errors(args) -> int:
    """``--proxy-errors``: each proxy against the full computation (module docstring)."""
    sys.path.insert(0, str(pathlib.Path(__file__).parent))
    import photo_bench as PB
    from _machine import cpu_model
    from pixgraph.session import Session
    repeat = args.repeat or 3
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}; python {sys.version.split()[0]}")
    rows = []
    for size in args.size or ["1280", "20mp"]:
        W, H = PB.SIZES[size]
        k = W / 640.0
        refr = PB.OUT / f"refraction_{size}.yaml"
        refr.write_text(REFRACTION.format(photo=PB.make_photo(size), horizon=120 * k, j0=262 * k, j1=292 * k,
                                          width=W, cu=450 * k, cv=400 * k))
        cases = [("reflection", PB.make_graph("glossy", size), "refl", "refl.layer"),
                 ("refraction", refr, "refr", "refr.layer")]
        for name, path, node, port in cases:
            if args.case and name not in args.case:
                continue
            s = Session(disk_cache=None, allow_paths=[str(ROOT)], cache_bytes=3 << 30)
            g = s.graph(path)
            cover = (s.run(g, outputs=["place.alpha"])["place.alpha"] if name == "reflection"
                     else s.run(g, outputs=["ball.alpha"])["ball.alpha"])
            saved = PB.OUT / f"full_{name}_{size}.npy"
            t0 = time.perf_counter()
            if saved.exists() and not args.recompute:
                full, t_full = np.load(saved), None
            else:
                full = np.asarray(s.run(g, outputs=[port], params={f"{node}.proxy": 0})[port], np.float32)
                t_full = time.perf_counter() - t0
                np.save(saved, full)
            if name == "refraction":
                # the method's floor: the hits traced at full size, looked up as the proxy does
                from pixgraph_nodes.ops import refraction as RF
                o = s.run(g, outputs=["cam.camera", "ball.image", "ball.height", "photo.image", "bg_h.height"])
                hh = RF.refraction_hits_cl(s.device, o["cam.camera"], o["ball.image"], o["ball.height"],
                                           o["bg_h.height"], eta=1.5, back_surface="local_sphere")
                yy, xx = np.nonzero(cover > 0)
                col = (hh["wts"][yy, xx, :1] * RF._bilinear(o["photo.image"], hh["pos"][yy, xx, 0], hh["pos"][yy, xx, 1])
                       + hh["wts"][yy, xx, 1:] * RF._bilinear(o["photo.image"], hh["pos"][yy, xx, 2],
                                                             hh["pos"][yy, xx, 3]))
                e = cover[yy, xx, None] * col - full[yy, xx, :3]
                row = {"case": name, "size": f"{W}x{H}", "proxy": "hits at full size", "pixels": "glass",
                       "n": int(yy.size), "rmse": float(np.sqrt(np.mean(e.astype(np.float64) ** 2))),
                       "max": float(np.abs(e).max())}
                rows.append(row)
                print(f"{name:10s} {W}x{H} hits traced at full size, looked up as the proxy does: RMSE "
                      f"{row['rmse']:.4f}  max {row['max']:.3f}  (the lookup's own difference)", flush=True)
                del hh, o
            if name == "reflection" and args.seed_floor:
                # the sampling noise: the full computation with another seed
                other = np.asarray(s.run(g, outputs=[port], params={f"{node}.proxy": 0, f"{node}.seed": 1})[port])
                d = other.astype(np.float64) - full
                where = ((other != 0).any(-1) | (full != 0).any(-1)) & (cover < 0.5)
                row = {"case": name, "size": f"{W}x{H}", "proxy": "full size, seed 1", "pixels": "affected",
                       "n": int(where.sum()), "rmse": float(np.sqrt(np.mean(d[where] ** 2))),
                       "max": float(np.abs(d[where]).max())}
                rows.append(row)
                print(f"{name:10s} {W}x{H} full computation with another seed: RMSE {row['rmse']:.4f}  "
                      f"max {row['max']:.3f}  (the sampling noise)", flush=True)
            for side in args.proxies:
                ts = []
                for _ in range(repeat):
                    s.memory.clear()
                    t0 = time.perf_counter()
                    out = np.asarray(s.run(g, outputs=[port], params={f"{node}.proxy": side})[port], np.float32)
                    ts.append(s.last_run.timings.get(node, time.perf_counter() - t0))
                d = out.astype(np.float64) - full
                if name == "reflection":
                    where = ((out != 0).any(-1) | (full != 0).any(-1)) & (cover < 0.5)
                    parts = [("affected", where)]
                    # where the layer's energy is: its alpha summed over bands of rows below the horizon
                    top = int(PB.SIZES[size][1] * 0.5)
                    edges = np.linspace(top, H, 7).astype(int)
                    print(f"  alpha sum per band of rows {', '.join(f'{a}-{b}' for a, b in zip(edges, edges[1:]))}: "
                          f"full {[round(float(full[a:b, :, 3].sum()), 1) for a, b in zip(edges, edges[1:])]}, "
                          f"proxy {side} {[round(float(out[a:b, :, 3].sum()), 1) for a, b in zip(edges, edges[1:])]}")
                else:
                    on = cover > 0
                    inner = on.copy()
                    for _ in range(6):
                        inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
                    parts = [("glass", on), ("interior", inner)]
                for label, where in parts:
                    e = d[where]
                    row = {"case": name, "size": f"{W}x{H}", "proxy": side, "pixels": label,
                           "n": int(where.sum()), "rmse": float(np.sqrt(np.mean(e ** 2))) if e.size else 0.0,
                           "max": float(np.abs(e).max()) if e.size else 0.0,
                           "node_s_median": statistics.median(ts), "full_s": t_full}
                    rows.append(row)
                    print(f"{name:10s} {W}x{H} proxy {side:5d} {label:9s} ({row['n']:9d} px): RMSE {row['rmse']:.4f}"
                          f"  max {row['max']:.3f}   node {row['node_s_median']:.2f} s (median of {repeat})"
                          + (f"; full computation {t_full:.1f} s" if t_full else ""), flush=True)
    print(f"load average at the end: {os.getloadavg()[0]:.2f}")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "proxy_errors.json").write_text(json.dumps(rows, indent=1))
    return 0


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=None)
    ap.add_argument("--proxy-errors", action="store_true", help="the proxies' error against the full computation")
    ap.add_argument("--size", action="append", choices=("512", "1280", "20mp"), help="--proxy-errors: photo size")
    ap.add_argument("--proxies", type=int, nargs="+", default=[1024, 512], help="--proxy-errors: proxy sides")
    ap.add_argument("--recompute", action="store_true", help="--proxy-errors: recompute the kept full layers")
    ap.add_argument("--case", action="append", choices=("reflection", "refraction"),
                    help="--proxy-errors: only these (default both)")
    ap.add_argument("--seed-floor", action="store_true",
                    help="--proxy-errors: also the full reflection with another seed (its sampling noise)")
    args = ap.parse_args(argv)
    if args.proxy_errors:
        return proxy_errors(args)
    repeat = args.repeat or (1 if args.quick else 3)
    dev = Device.open()
    print(f"machine: {platform.node()} {platform.machine()} {platform.processor() or ''} "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()}")
    print(f"device: {dev.name}")
    sc = scene()
    cam, cut, fg, bg = sc
    results = {"machine": platform.node(), "cpus": os.cpu_count(), "device": dev.name,
               "load_start": os.getloadavg(), "repeat": repeat, "mirror": {}, "glossy": {}}
    R.reflection_cl(dev, cam, cut, fg, bg, roughness=0.2, min_spp=1, max_spp=1)     # build, warm up

    # -- mirror ---------------------------------------------------------------
    print("\nmirror (roughness 0), 512x512, one sample per pixel")
    mir = {}
    for label, kw in (("planar closed form", dict(planar=True)),
                      ("traced, Hi-Z", dict(planar=False, hiz=True)),
                      ("traced, plain march", dict(planar=False, hiz=False))):
        t, ts, r = timed(lambda: R.reflection_cl(dev, cam, cut, fg, bg, roughness=0.0, **kw), max(repeat, 5))
        mir[label] = r["layer"]
        results["mirror"][label] = {"median_s": t, "runs_s": ts, "steps_per_px": float(r["steps"].mean())}
        print(f"  {label:22s} {t * 1e3:8.1f} ms  (runs {', '.join(f'{x * 1e3:.0f}' for x in ts)} ms)  "
              f"march steps/px {r['steps'].mean():.1f}")
    for label in ("traced, Hi-Z", "traced, plain march"):
        d = float(np.abs(mir[label] - mir["planar closed form"]).max())
        results["mirror"][label]["max_abs_diff_vs_closed_form"] = d
        print(f"  max |{label} - closed form| = {d:.2e}")

    # -- glossy ---------------------------------------------------------------
    fixed = [4, 16, 64] if args.quick else [4, 8, 16, 32, 64, 128, 200]
    plain = [16] if args.quick else [16, 64]
    targets = [0.02, 0.01] if args.quick else [0.04, 0.02, 0.01, 0.005]
    for name, mat in MATERIALS.items():
        print(f"\nglossy {name} {mat}, 512x512")
        ref, ref_t = reference(dev, sc, name, mat)
        rows = []

        def run(kind, label, **kw):
            t, ts, r = timed(lambda: R.reflection_cl(dev, cam, cut, fg, bg, seed=7, **mat, **kw), repeat)
            e = rmse(r["layer"], ref)
            row = {"kind": kind, "label": label, "median_s": t, "runs_s": ts, "rmse": e,
                   "mean_spp": float(r["spp"].mean()), "steps_per_px": float(r["steps"].mean())}
            rows.append(row)
            print(f"  {kind:14s} {label:>14s}  {t:7.2f} s  RMSE {e:.4f}  mean spp {row['mean_spp']:6.1f}  "
                  f"steps/px {row['steps_per_px']:8.1f}", flush=True)

        for n in fixed:
            run("fixed Hi-Z", f"{n} spp", min_spp=n, max_spp=n)
        for n in plain:
            run("fixed plain", f"{n} spp", min_spp=n, max_spp=n, hiz=False)
        for t in targets:
            run("adaptive Hi-Z", f"se {t:g}", min_spp=16, max_spp=128, target_se=t)
        results["glossy"][name] = {"material": mat, "reference_s": ref_t, "runs": rows}
    results["load_end"] = os.getloadavg()
    print(f"\nload average at the end: {results['load_end']}")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "reflection_bench.json").write_text(json.dumps(results, indent=1, default=str))
    chart(results)
    return 0


def chart(results):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(results["glossy"])
    fig, axes = plt.subplots(1, len(names), figsize=(5.2 * len(names), 4.2), squeeze=False)
    style = {"fixed Hi-Z": ("o-", "C0"), "fixed plain": ("s--", "C3"), "adaptive Hi-Z": ("^-", "C2")}
    for ax, name in zip(axes[0], names):
        runs = results["glossy"][name]["runs"]
        for kind, (mk, c) in style.items():
            rs = [r for r in runs if r["kind"] == kind]
            if not rs:
                continue
            ax.plot([r["median_s"] for r in rs], [r["rmse"] for r in rs], mk, color=c,
                    label=kind + (" (16..128 spp)" if kind.startswith("adaptive") else ""))
            for r in rs:
                ax.annotate(r["label"].replace(" spp", ""), (r["median_s"], r["rmse"]), fontsize=7,
                            xytext=(3, 3), textcoords="offset points")
        ax.axhline(TARGET_RMSE, color="k", lw=0.8, ls=":", label="RMSE 0.005")
        ax.axvline(7.0, color="grey", lw=0.8, ls="-.", label="paper: 7 s (CUDA GPU)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time [s] (median)")
        ax.set_ylabel("RMSE vs reference")
        ax.set_title(f"512² glossy reflection, {name}")
        ax.grid(True, which="both", lw=0.3)
        ax.legend(fontsize=7)
    m = results["mirror"]
    fig.suptitle("pixgraph reflection: " + results["device"][:60] + "\nmirror 512²: " +
                 ", ".join(f"{k} {v['median_s'] * 1e3:.0f} ms" for k, v in m.items()), fontsize=8)
    fig.tight_layout()
    CHART.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(CHART, dpi=90)
    print(f"chart: {CHART}")


if __name__ == "__main__":
    sys.exit(main())
