"""Photo-size benchmark (issue 22): the own-photo soft shadow and the glossy
reflection on a 20-megapixel photo (5120x3840) and on the same photo at 512x384.

    python benchmarks/photo_bench.py                      # both graphs, both sizes, 3 runs each
    python benchmarks/photo_bench.py --case soft --size 20mp --repeat 1
    python benchmarks/photo_bench.py --case soft --size 20mp --profile   # where the time goes (cProfile)
    python benchmarks/photo_bench.py --case soft --size 20mp --profile --profile-cpu   # ... in CPU seconds

The photo is made here, from the repository's own asset (graphs/assets/own_photo.jpg,
rendered by graphs/assets/make_own_photo.py): enlarged 8x and given a deterministic
film grain and a fine plaster/wood texture, so that it encodes like a photo (no
third-party picture). Its cutout is graphs/assets/own_cutout.png (159x285), placed
at 6.4x its size on the 20 MP photo (0.64x at 512). Both are written under
out/bench/photo/ (gitignored), once.

Cases (the graphs are written next to the photo):

* ``soft``: graphs/own_photo.yaml at the photo's size: LoadImage x2, Camera from
  the photo, CutoutHeight, PlaceCutout, BackgroundHeight (back wall), Light,
  SoftShadow (48 samples), Composite; the final is written as PNG and as JPEG.
* ``glossy``: the same scene with the floor glossy (Reflection: roughness 0.2,
  dielectric, receivers ground) and ReflectionComposite, as graphs/glossy_floor.yaml.

Sizes: ``50mp`` (8192x6144), ``20mp`` (5120x3840), ``5mp`` (2560x1920), ``1280`` (1280x960), ``512``
(512x384); the cutout is placed at 0.8x (640 / photo width) its size.

Each run is a fresh process (``pixgraph run`` as a user runs it) with an empty
memory cache and a disk cache folder of its own: ``s`` is the wall-clock of
``Session.run`` plus writing the file (``cpu``: the process's CPU seconds, all
threads: on a loaded shared machine the less noisy number), ``peak_mib`` the process's peak resident
memory (VmHWM, Linux), ``disk_mib`` how much the disk cache grew. The medians are
printed with the machine and its load. Nothing here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import json
import os
import pathlib
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

from _machine import cpu_model, peak_rss_mib

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "out" / "bench" / "photo"
ASSETS = ROOT / "graphs" / "assets"
#: (width, height) of each size; the own photo is 640x480 (4:3)
SIZES = {"50mp": (8192, 6144), "20mp": (5120, 3840), "5mp": (2560, 1920), "1280": (1280, 960), "512": (512, 384)}

GRAPH = """pixgraph: 1
nodes:
  cutout: {{type: pixgraph.LoadImage, params: {{path: {cutout}}}}}
  photo:  {{type: pixgraph.LoadImage, params: {{path: {photo}}}}}
  cam:    {{type: pixgraph.Camera, inputs: {{image: photo.image}}, params: {{horizon: {horizon}}}}}
  fg_h:   {{type: pixgraph.CutoutHeight, inputs: {{mask: cutout.alpha}}}}
  place:
    type: pixgraph.PlaceCutout
    inputs: {{cutout: cutout.image, background: photo.image, height: fg_h.height}}
    params: {{foot: [{foot_u}, {foot_v}], scale: {scale}}}
  bg_h:
    type: pixgraph.BackgroundHeight
    inputs: {{camera: cam.camera}}
    params: {{kind: back_wall, junction_points: [0, {j0}, {width}, {j1}]}}
  light:
    type: pixgraph.Light
    inputs: {{camera: cam.camera, mask: place.alpha}}
    params: {{azimuth: -30, elevation: 28, radius: 0.3}}
  shadow:
    type: pixgraph.SoftShadow
    inputs: {{mask: place.alpha, fg_height: place.height, bg_height: bg_h.height, light: light.light, camera: cam.camera}}
    params: {{samples: 48, thickness: {thickness}}}
{extra}outputs: {{final: comp.image}}
"""
SOFT = """  comp:
    type: pixgraph.Composite
    inputs: {background: photo.image, cutout: place.image, alpha: place.alpha, shadow: shadow.darkness}
"""
GLOSSY = """  refl:
    type: pixgraph.Reflection
    inputs: {camera: cam.camera, cutout: place.image, fg_height: place.height, bg_height: bg_h.height}
    params: {roughness: 0.2, material: dielectric, eta: 1.5, thickness: %s, receivers: ground,
             noise: 0.005, min_spp: 16, max_spp: 128}
  comp:
    type: pixgraph.ReflectionComposite
    inputs: {background: photo.image, cutout: place.image, alpha: place.alpha,
             reflection: refl.layer, shadow: shadow.darkness}
"""


def make_photo(size: str) -> pathlib.Path:
    """The photo of ``size`` (cached under out/bench/photo/): own_photo.jpg enlarged
    (bilinear), with a fine texture and film grain in sRGB, written as JPEG q 95."""
    from pixgraph_nodes.ops.imageio import read_image, write_image
    from pixgraph_nodes.ops.resample import resize
    W, H = SIZES[size]
    path = OUT / f"photo_{W}x{H}.jpg"
    if path.exists():
        return path
    OUT.mkdir(parents=True, exist_ok=True)
    img, _ = read_image(ASSETS / "own_photo.jpg")
    big = np.stack([resize(img[:, :, c], (H, W)) for c in range(3)], axis=2)
    rng = np.random.default_rng(22)
    k = W / 640.0
    if k > 1:   # detail the 640-px original does not have: a 2-8 px mottle and grain
        coarse = rng.standard_normal((H // 4 + 2, W // 4 + 2)).astype(np.float32)
        mottle = resize(coarse, (H + 8, W + 8))[4:H + 4, 4:W + 4]
        big *= (1.0 + 0.04 * mottle)[:, :, None]
        big *= (1.0 + 0.02 * rng.standard_normal((H, W), dtype=np.float32))[:, :, None]
    write_image(path, np.clip(big, 0.0, 1.0))
    return path


def make_graph(case: str, size: str) -> pathlib.Path:
    W, H = SIZES[size]
    k = W / 640.0
    photo = make_photo(size)
    text = GRAPH.format(cutout=ASSETS / "own_cutout.png", photo=photo, horizon=120 * k,
                        foot_u=270 * k, foot_v=345 * k, scale=round(0.8 * k, 4), j0=262 * k, j1=292 * k,
                        width=W, thickness=6 * k,
                        extra=SOFT if case == "soft" else GLOSSY % (4 * k))
    path = OUT / f"{case}_{size}.yaml"
    path.write_text(text)
    return path


def _folder_bytes(folder: str) -> int:
    return sum(f.stat().st_size for f in pathlib.Path(folder).rglob("*") if f.is_file())


def one(a) -> int:
    """Subprocess mode: one run of one graph in a fresh process; prints JSON."""
    from pixgraph.session import Session
    from pixgraph_nodes.ops.imageio import write_image
    graph = make_graph(a.case, a.size)
    cache = tempfile.mkdtemp(prefix="photo-bench-cache-")
    try:
        s = Session(disk_cache=None if a.no_disk_cache else cache, allow_paths=[str(ROOT)])
        dest = OUT / f"final_{a.case}_{a.size}{a.ext}"
        kw = {"params": {"shadow.proxy": a.shadow_proxy}} if a.shadow_proxy is not None else {}
        prof = None
        if a.profile:
            import cProfile
            # --profile-cpu: process CPU seconds (all threads) instead of wall-clock, the
            # steadier number on a loaded machine
            prof = cProfile.Profile(time.process_time) if a.profile_cpu else cProfile.Profile()
            prof.enable()
        import resource
        r0 = resource.getrusage(resource.RUSAGE_SELF)
        t0 = time.perf_counter()
        out = s.run(graph, **kw)
        t1 = time.perf_counter()
        write_image(dest, out["final"])
        t2 = time.perf_counter()
        r1 = resource.getrusage(resource.RUSAGE_SELF)
        cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
        if prof is not None:
            prof.disable()
            import pstats
            pstats.Stats(prof, stream=sys.stderr).sort_stats("cumulative").print_stats(45)
        timings = dict(sorted(s.last_run.timings.items(), key=lambda kv: -kv[1]))
        print(json.dumps({"s": t2 - t0, "cpu_s": cpu, "run_s": t1 - t0, "write_s": t2 - t1, "peak_mib": peak_rss_mib(),
                          "disk_mib": _folder_bytes(cache) / 2**20, "file_mib": dest.stat().st_size / 2**20,
                          "nodes": {k: round(v, 3) for k, v in timings.items()}}))
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return 0


def errors(a) -> int:
    """``--errors``: each proxy against the full computation on the photo of ``--size``:
    SoftShadow's darkness (proxy 0 = full trace, against 512/1024/2048), the glossy
    Reflection layer (proxy 0 against 512/1024), and a whole preview at working
    resolution ``--preview-scale`` (darkness against the full run's, downsampled).
    RMSE over background pixels (outside the placed cutout) and max |error|."""
    from pixgraph.session import Session
    from pixgraph_nodes.ops.resample import at_scale
    size = a.size[0] if a.size else "20mp"
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}; size {SIZES[size]}")
    s = Session(disk_cache=None, allow_paths=[str(ROOT)], cache_bytes=1 << 30)

    def rmse(x, ref, where):
        d = (np.asarray(x, np.float64) - ref)[where]
        return float(np.sqrt(np.mean(d ** 2))), float(np.abs(d).max())
    for case in a.case or ["soft", "glossy"]:
        g = s.graph(make_graph(case, size))
        what, port = ("shadow", "shadow.darkness") if case == "soft" else ("refl", "refl.layer")
        alpha = s.run(g, outputs=["place.alpha"])["place.alpha"]
        bgpx = alpha < 0.5
        saved = OUT / f"full_{case}_{size}.npy"      # the full computation takes minutes: kept for reruns
        t0 = time.perf_counter()
        if saved.exists() and not a.recompute:
            full = np.load(saved).astype(np.float64)
            print(f"{case}: full computation read from {saved.relative_to(ROOT)}", flush=True)
        else:
            full = np.array(s.run(g, outputs=[port], params={f"{what}.proxy": 0})[port], np.float64)
            np.save(saved, full.astype(np.float32))
            print(f"{case}: full computation {time.perf_counter() - t0:.1f} s", flush=True)
        for side in a.proxies:
            t0 = time.perf_counter()
            out = s.run(g, outputs=[port], params={f"{what}.proxy": side})[port]
            sec = time.perf_counter() - t0
            e, m = rmse(out, full, bgpx)
            if a.save:
                np.save(OUT / f"proxy{side}_{case}_{size}.npy", np.asarray(out, np.float32))
            print(f"  {port} proxy {side:5d}: RMSE {e:.4f}  max {m:.3f}  ({sec:.1f} s)", flush=True)
        if case == "soft":
            sc = a.preview_scale
            lo = s.run(g, outputs=[port], scale=sc)[port]
            ref = at_scale(full.astype(np.float32), sc)
            e, m = rmse(lo, ref, at_scale(alpha, sc) < 0.5)
            print(f"  preview at scale {sc} ({lo.shape[1]}x{lo.shape[0]}): darkness RMSE {e:.4f} max {m:.3f} "
                  "against the full trace downsampled", flush=True)
            final = s.run(g, outputs=[port])[port]             # the final as it runs (default proxy)
            e, m = rmse(lo, at_scale(final, sc), at_scale(alpha, sc) < 0.5)
            print(f"  preview at scale {sc}: darkness RMSE {e:.4f} max {m:.3f} against the final (default "
                  "proxy) downsampled: what the preview shows of the final", flush=True)
        s.memory.clear() if hasattr(s.memory, "clear") else None
    return 0


def drag(a) -> int:
    """``--drag``: a light drag on the photo of ``--size`` previewed at a ~1 MP working
    resolution (``Session.run(scale=...)``): the first run (loading included), then
    three light positions per ``shadow.proxy`` in ``--proxies`` (only light, shadow
    and composite rerun); median wall-clock and CPU seconds."""
    import resource
    from pixgraph.session import Session
    size = a.size[0] if a.size else "20mp"
    W, H = SIZES[size]
    sc = min(1.0, (1e6 / (W * H)) ** 0.5)
    s = Session(disk_cache=None, allow_paths=[str(ROOT)])
    g = s.graph(make_graph("soft", size))
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f}; {W}x{H} at scale {sc:.4f}")
    t0 = time.perf_counter()
    out = s.run(g, scale=sc)
    print(f"first preview {out['final'].shape[1]}x{out['final'].shape[0]}: {time.perf_counter() - t0:.2f} s")

    def cpu():
        r = resource.getrusage(resource.RUSAGE_SELF)
        return r.ru_utime + r.ru_stime
    for k, side in enumerate(a.proxies):
        walls, cpus = [], []
        for az in (-20.0, -10.0, 0.0):
            c0, t0 = cpu(), time.perf_counter()
            s.run(g, scale=sc, params={"light.azimuth": az + 0.1 * k, "shadow.proxy": side})
            walls.append(time.perf_counter() - t0)
            cpus.append(cpu() - c0)
        print(f"light drag, shadow.proxy {side}: median {statistics.median(walls):.3f} s wall, "
              f"{statistics.median(cpus):.3f} CPU s; reran {', '.join(s.last_run.ran)}; "
              f"load {os.getloadavg()[0]:.2f}")
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", action="append", choices=("soft", "glossy"))
    ap.add_argument("--size", action="append", choices=tuple(SIZES))
    ap.add_argument("--ext", action="append", choices=(".png", ".jpg"),
                    help="output format(s) of the final (default both for soft, .png for glossy)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--shadow-proxy", type=int, default=None, help="SoftShadow's proxy param (default: its own)")
    ap.add_argument("--no-disk-cache", action="store_true")
    ap.add_argument("--profile", action="store_true", help="one run under cProfile (printed to stderr)")
    ap.add_argument("--profile-cpu", action="store_true", help="--profile counts process CPU seconds, not wall-clock")
    ap.add_argument("--errors", action="store_true", help="each proxy's error against the full computation")
    ap.add_argument("--proxies", type=int, nargs="+", default=[512, 1024, 2048])
    ap.add_argument("--recompute", action="store_true", help="--errors: recompute the saved full computation")
    ap.add_argument("--save", action="store_true", help="--errors: save each proxy's result next to it")
    ap.add_argument("--preview-scale", type=float, default=0.2236, help="--errors: scale of the preview (~1 MP)")
    ap.add_argument("--drag", action="store_true", help="light drags previewed at ~1 MP (--proxies: shadow.proxy)")
    ap.add_argument("--one", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.errors:
        return errors(a)
    if a.drag:
        return drag(a)
    if a.one:
        a.case, a.size, a.ext = a.case[0], a.size[0], a.ext[0]
        return one(a)
    cases, sizes = a.case or ["soft", "glossy"], a.size or ["512", "20mp"]
    print(f"machine: {cpu_model()}; load average {os.getloadavg()[0]:.2f} at start; python {sys.version.split()[0]}")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(pathlib.Path(__file__).parent),
                                                                     os.environ.get("PYTHONPATH")])))
    for case in cases:
        for size in sizes:
            make_graph(case, size)     # build the assets off the clock
            for ext in a.ext or ([".png", ".jpg"] if case == "soft" else [".png"]):
                rows = []
                for _ in range(1 if a.profile else a.repeat):
                    cmd = [sys.executable, __file__, "--one", "--case", case, "--size", size, "--ext", ext]
                    cmd += ["--no-disk-cache"] if a.no_disk_cache else []
                    cmd += ["--profile"] if a.profile else []
                    cmd += ["--profile-cpu"] if a.profile_cpu else []
                    if a.shadow_proxy is not None:
                        cmd += ["--shadow-proxy", str(a.shadow_proxy)]
                    p = subprocess.run(cmd, capture_output=True, text=True, env=env)
                    if p.returncode != 0:
                        print(p.stdout, p.stderr, file=sys.stderr)
                        return 1
                    if a.profile:
                        print(p.stderr)
                    rows.append(json.loads(p.stdout.strip().splitlines()[-1]))
                med = {k: statistics.median(r[k] for r in rows)
                       for k in ("s", "cpu_s", "run_s", "write_s", "peak_mib", "disk_mib", "file_mib")}
                print(f"{case:6s} {size:5s} {ext:4s} n={len(rows)}  total {med['s']:7.2f} s  (run {med['run_s']:.2f}"
                      f" + write {med['write_s']:.2f}; cpu {med['cpu_s']:.2f} s)  peak {med['peak_mib']:6.0f} MiB  disk cache "
                      f"+{med['disk_mib']:6.1f} MiB  file {med['file_mib']:.1f} MiB  load {os.getloadavg()[0]:.2f}")
                nodes = {k: statistics.median(r["nodes"].get(k, 0.0) for r in rows) for k in rows[-1]["nodes"]}
                print(f"        slowest nodes (median of {len(rows)}):",
                      ", ".join(f"{k} {v:.2f}s" for k, v in sorted(nodes.items(), key=lambda kv: -kv[1])[:6]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
