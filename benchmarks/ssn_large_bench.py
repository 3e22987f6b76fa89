"""SSN++ on a large non-square image: the old whole-frame squeeze against the
window at the trained scale (``ops.ssn_crop``), on benchmark scenes enlarged 4x
and cropped to 1024 x 700 (``pixgraph_lab.rescale``).

    python benchmarks/ssn_large_bench.py --data data/wall_test --limit 20

Per method, mean over the samples (medians for time):

* ``rmse_gt``: RMSE against the Mitsuba ground truth, the prediction shrunk back
  to the 256-px scale (area average), over the benchmark's valid pixels;
* ``vs256``: RMSE between that shrunk prediction and the same method on the
  original 256^2 sample (scale consistency; 0 = the image size changes nothing);
* ``halo``: mean and max darkness on background pixels within 3 px of the
  cutout where the ground truth is lit (< 0.01); ``halo (classical)``: the
  mean where the classical soft shadow (16 samples, full resolution) is 0, as
  the issue measured it;
* ``far``: max darkness on pixels more than 48 px (full res) from every
  ground-truth shadow pixel (> 0.01) and from the cutout (corner darkening);
* ``ms``: median wall-clock of the whole prediction (buffer channels + network).

Nothing here is asserted by the tests.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np
from scipy import ndimage

from _machine import cpu_model


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default="data/wall_test")
    ap.add_argument("--limit", type=int, default=20)
    ap.add_argument("--factor", type=int, default=4)
    ap.add_argument("--height", type=int, default=700)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)

    import torch
    torch.set_num_threads(1)
    from pixgraph.device import Device
    from pixgraph_lab.datagen.dataset import sample_files
    from pixgraph_lab.evaluate import prepared_sample
    from pixgraph_lab.metrics import shadow_metrics
    from pixgraph_lab.rescale import rescaled
    from pixgraph_nodes.ops import ssn, ssn_crop
    from pixgraph_nodes.ops.buffers import buffer_channels
    from pixgraph_nodes.ops.lights import disk_extremes, disk_samples, light_point
    from pixgraph_nodes.ops.shadow import soft_shadow
    from pixgraph_nodes.ops.resample import resize
    from pixgraph_nodes.ssn_soft_shadow import load_shipped

    dev = Device.open()
    model = load_shipped("ssnpp")

    def before(s):   # the node up to this change: whole frame squeezed to 256^2
        L, c = s["light"], s["camera"]
        m = s["mask"].astype(np.float32)
        b = buffer_channels(dev, m, s["fg_height"], s["bg_height"], light_point(L, c), disk_extremes(L, c), 1.0)
        return ssn.predict(model, b, ssn.softness_of(L, c, m, s["fg_height"]))

    def after(s):
        L, c = s["light"], s["camera"]
        m = s["mask"].astype(np.float32)
        return ssn_crop.render(dev, model, m, s["fg_height"], s["bg_height"], light_point(L, c),
                               disk_extremes(L, c), ssn.softness_of(L, c, m, s["fg_height"]), 1.0)[0]

    methods = {"before (squeeze)": before, "after (window)": after}
    rows = {k: [] for k in methods}
    f = a.factor
    for path in sample_files(a.data)[:a.limit]:
        s = prepared_sample(path, dev)
        big = rescaled(s, f, a.height)
        r0, nr = big["rows"] // f, a.height // f
        g = s["shadow"][r0:r0 + nr].astype(np.float64)
        valid = (~s["mask"] & s["bg_valid"])[r0:r0 + nr]
        inside = big["mask"]
        ring = (ndimage.distance_transform_edt(~inside) <= 3) & ~inside & (big["shadow"] < 0.01)
        lit16 = soft_shadow(dev, inside.astype(np.float32), big["fg_height"], big["bg_height"],
                            disk_samples(big["light"], big["camera"], 16), 1.0)
        ring_c = (ndimage.distance_transform_edt(~inside) <= 3) & ~inside & (lit16 >= 1.0)
        far = ndimage.distance_transform_edt(~((big["shadow"] > 0.01) | inside)) > 48
        for name, fn in methods.items():
            small = fn(s)[r0:r0 + nr]
            fn(big)                                   # warm (first call builds programs)
            t0 = time.perf_counter()
            d = fn(big)
            ms = 1e3 * (time.perf_counter() - t0)
            d_small = resize(d, (nr, d.shape[1] // f))
            rows[name].append({
                "rmse_gt": shadow_metrics(np.clip(d_small, 0, 1), g, valid)["rmse"],
                "vs256": float(np.sqrt(np.mean((d_small[valid] - small[valid]) ** 2))),
                "halo_mean": float(d[ring].mean()) if ring.any() else 0.0,
                "halo_max": float(d[ring].max()) if ring.any() else 0.0,
                "halo_classical": float(d[ring_c].mean()) if ring_c.any() else 0.0,
                "far_max": float(d[far].max()) if far.any() else 0.0, "ms": ms})
    H, W = a.height, 256 * f
    print(f"# SSN++ on {W}x{H} (benchmark scenes x{f}), {len(rows['after (window)'])} samples of {a.data}; "
          f"{cpu_model()}, torch 1 thread")
    print("| method | RMSE vs GT | RMSE vs 256² run | halo mean | halo max | halo (classical) | far max | ms (median) |")
    print("|---|---|---|---|---|---|---|---|")
    out = {}
    for name, rs in rows.items():
        mean = {k: float(np.mean([r[k] for r in rs])) for k in rs[0]}
        mean["halo_max"] = float(np.max([r["halo_max"] for r in rs]))
        mean["far_max"] = float(np.max([r["far_max"] for r in rs]))
        mean["ms"] = statistics.median(r["ms"] for r in rs)
        out[name] = mean
        print(f"| {name} | {mean['rmse_gt']:.4f} | {mean['vs256']:.4f} | {mean['halo_mean']:.4f} | "
              f"{mean['halo_max']:.3f} | {mean['halo_classical']:.4f} | {mean['far_max']:.3f} | {mean['ms']:.0f} |")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"machine": cpu_model(), "rows": rows, "summary": out}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
