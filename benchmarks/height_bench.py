"""Learned cutout pixel-height inference time at 256^2 on this machine (goal: <= 30 ms, issue 24).

    python benchmarks/height_bench.py [--weights nodes/weights/cutout_height.pt] [--threads N] [--runs 31]
    python benchmarks/height_bench.py --size 2048 --runs 9 --own-size     # a large cutout: the work-size path
    python benchmarks/height_bench.py --size 400 --canvas 5120x3840 --runs 9   # a matte at a 20 MP photo's size
    python benchmarks/height_bench.py --backend both --runs 31            # numpy vs torch network, alternating
    python benchmarks/height_bench.py --first-use 5                       # a fresh process's first prediction
    python benchmarks/height_bench.py --compare data/hreal/test   # numpy vs torch maps on a split

``--backend``: where the network runs (``LearnedHeightPredictor(backend=...)``):
``numpy`` (ops/height_net.py), ``torch``, or ``both``: the two timed run by run
alternately on the same cutout (ratios on a busy machine), with the largest
difference of their maps. ``--first-use N``: N fresh Python processes per
backend, alternating, each timing its imports (``pixgraph_nodes.ops.learned_height``,
and torch for the torch backend), loading the predictor, the first and the
second ``predict_full`` (medians reported). ``--compare DIR``: no timing; every
height sample of DIR (``generate`` output) predicted by both backends: the
largest differences of the maps, of their MAE against the true height, of the
confidence signal, and how often auto's choice differs.

Times, median (and min) wall time and median process CPU time over ``--runs`` after warm-up, on a ``--size``
square RGBA cutout (default 256; a shaded upright figure-like shape drawn procedurally, filling about
half the image): the whole ``LearnedHeightPredictor.predict`` (crop, resize,
the contact-line channel, the network, paste back) and the network alone; and
the contact-line heuristic for comparison; with ``--own-size`` also the path
shipped before the fifth session, alternating run by run with the shipped one
(a cutout larger than 512 px is now predicted at 512 px). Nothing here is
asserted by the tests.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import statistics
import sys
import time

import numpy as np

from _machine import cpu_model

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_cutout(size: int = 256) -> np.ndarray:
    """A premultiplied RGBA (size, size, 4): an ellipse body on two legs, shaded."""
    v, u = np.mgrid[0:size, 0:size] + 0.5
    s = size / 256
    body = ((u - 128 * s) / (40 * s)) ** 2 + ((v - 100 * s) / (60 * s)) ** 2 < 1
    legs = ((np.abs(u - 112 * s) < 8 * s) | (np.abs(u - 144 * s) < 8 * s)) & (v > 140 * s) & (v < 220 * s)
    a = (body | legs).astype(np.float32)
    shade = 0.3 + 0.6 * np.clip((u - 80 * s) / (100 * s), 0, 1)
    rgb = np.stack([0.8 * shade, 0.4 * shade, 0.3 * shade], -1) * a[..., None]
    return np.concatenate([rgb, a[..., None]], -1).astype(np.float32)


def timed(fn, runs: int) -> tuple[float, float, float]:
    """(median wall ms, min wall ms, median process CPU ms: user + sys of this process,
    which a busy machine inflates less than wall time)."""
    fn(); fn()
    ts, cs = [], []
    for _ in range(runs):
        c0, t0 = time.process_time(), time.perf_counter()
        fn()
        ts.append(1e3 * (time.perf_counter() - t0))
        cs.append(1e3 * (time.process_time() - c0))
    return statistics.median(ts), min(ts), statistics.median(cs)


def timed_alternating(fns: dict, runs: int) -> dict:
    """``timed`` for several functions, run in turn within each run: {name: (median wall ms,
    min wall ms, median CPU ms)}."""
    for fn in fns.values():
        fn(); fn()
    ts = {k: [] for k in fns}
    cs = {k: [] for k in fns}
    for _ in range(runs):
        for k, fn in fns.items():
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            ts[k].append(1e3 * (time.perf_counter() - t0))
            cs[k].append(1e3 * (time.process_time() - c0))
    return {k: (statistics.median(ts[k]), min(ts[k]), statistics.median(cs[k])) for k in fns}


FIRST_USE = r"""
import json, sys, time
t0 = time.perf_counter(); c0 = time.process_time()
backend, size, weights = sys.argv[1], int(sys.argv[2]), sys.argv[3]
sys.path.insert(0, sys.argv[4])
from height_bench import test_cutout
rgba = test_cutout(size)
t1 = time.perf_counter()
if backend == "torch":
    import torch
from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor
t2 = time.perf_counter()
pred = LearnedHeightPredictor(weights, backend=backend)
t3 = time.perf_counter()
pred.predict_full(rgba)
t4 = time.perf_counter()
pred.predict_full(rgba)
t5 = time.perf_counter()
print(json.dumps({"import": t2 - t1, "load": t3 - t2, "first": t4 - t3, "second": t5 - t4,
                  "total": t4 - t1, "cpu": time.process_time() - c0, "torch": "torch" in sys.modules}))
"""


def first_use(n: int, size: int, weights: str, backends) -> None:
    """Fresh processes, alternating between ``backends``: import, load, first and second predict [ms]."""
    import json
    import subprocess
    rows = {b: [] for b in backends}
    env = dict(os.environ, OMP_NUM_THREADS="1")
    for _ in range(n):
        for b in backends:
            out = subprocess.run([sys.executable, "-c", FIRST_USE, b, str(size), weights, str(ROOT / "benchmarks")],
                                 capture_output=True, text=True, check=True, env=env)
            rows[b].append(json.loads(out.stdout.strip().splitlines()[-1]))
    print(f"first use in a fresh process, {size}x{size} cutout, median of {n} processes per backend "
          f"(alternating), wall ms [CPU ms of the whole process]; load average {os.getloadavg()[0]:.1f}:")
    for b in backends:
        med = {k: 1e3 * statistics.median(r[k] for r in rows[b]) for k in ("import", "load", "first", "second",
                                                                         "total", "cpu")}
        print(f"  {b:6s} imports {med['import']:7.0f}  load {med['load']:6.0f}  first predict {med['first']:6.0f}"
              f"  = {med['total']:6.0f} ms [{med['cpu']:.0f}]; second predict {med['second']:.0f} ms; "
              f"torch imported: {rows[b][0]['torch']}")


def compare(data_dir: str, weights: str) -> None:
    """numpy vs torch predict_full on every height sample of ``data_dir``."""
    from pixgraph_lab.height.evaluate import height_files, read_height_sample
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor
    num = LearnedHeightPredictor(weights, backend="numpy")
    tor = LearnedHeightPredictor(weights, backend="torch")
    dh, dmae, dsig, dconf, flips, n, mae = 0.0, 0.0, 0.0, 0.0, 0, 0, []
    for f in height_files(data_dir):
        _, rgba, true, mask = read_height_sample(f)
        a, b = num.predict_full(rgba), tor.predict_full(rgba)
        if not mask.any():
            continue
        n += 1
        dh = max(dh, float(np.abs(a["height"] - b["height"]).max()))
        ma, mb = (float(np.abs(r["auto_height"][mask] - true[mask]).mean()) for r in (a, b))
        mae.append(ma)
        dmae = max(dmae, abs(ma - mb))
        dsig = max(dsig, abs(a["signal"] - b["signal"]))
        dconf = max(dconf, abs(a["confidence"] - b["confidence"]))
        flips += a["use_learned"] != b["use_learned"]
    print(f"{data_dir}: {n} samples, numpy vs torch predict_full: largest |height difference| {dh:.2e} px, "
          f"largest |auto MAE difference| {dmae:.2e} px (auto MAE {np.mean(mae):.3f} px), largest |signal "
          f"difference| {dsig:.2e}, largest |confidence difference| {dconf:.2e}, auto's choice differs on {flips}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weights", default=str(ROOT / "nodes" / "weights" / "cutout_height.pt"))
    ap.add_argument("--threads", type=int, default=1,
                    help="threads of the predictor's network, torch's or numpy's BLAS's (its default is 1; "
                         "0: the library's default)")
    ap.add_argument("--runs", type=int, default=31)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--backend", choices=("numpy", "torch", "both"), default="both",
                    help="where the network runs; both: numpy and torch alternating (default)")
    ap.add_argument("--first-use", type=int, default=0, metavar="N",
                    help="instead: N fresh processes per backend, import + load + first predict")
    ap.add_argument("--canvas", metavar="WxH", default=None,
                    help="the cutout in the middle of a transparent canvas this size (a matte at a photo's size)")
    ap.add_argument("--compare", default=None, metavar="DIR",
                    help="instead: numpy vs torch on every height sample of DIR (maps, MAE, auto's choice)")
    ap.add_argument("--baseline", default=None,
                    help="a second checkpoint timed in the same run, interleaved (ratios on a busy machine)")
    ap.add_argument("--own-size", action="store_true",
                    help="also time the path shipped before the fifth session (everything at the cutout's own "
                         "size: work_side = signal_side = None), alternating with the shipped one")
    a = ap.parse_args(argv)
    backends = ("numpy", "torch") if a.backend == "both" else (a.backend,)
    sys.path.insert(0, str(ROOT))
    if a.first_use:
        print(f"machine: {cpu_model()}")
        first_use(a.first_use, a.size, a.weights, backends)
        return 0
    if a.compare:
        compare(a.compare, a.weights)
        return 0
    from pixgraph_nodes.ops import height_net
    from pixgraph_nodes.ops.heightmaps import contact_line_height
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor, prepare, straight_srgb
    preds = {b: LearnedHeightPredictor(a.weights, threads=a.threads or None, backend=b) for b in backends}
    pred = preds[backends[0]]
    rgba = test_cutout(a.size)
    if a.canvas:
        cw, ch = (int(v) for v in a.canvas.lower().split("x"))
        canvas = np.zeros((ch, cw, 4), np.float32)
        top, left = (ch - a.size) // 2, (cw - a.size) // 2
        canvas[top:top + a.size, left:left + a.size] = rgba
        rgba = canvas
    colour, alpha = straight_srgb(rgba)
    x, _, _ = prepare(colour, alpha, pred.size)
    xs = np.stack([x, x[:, :, ::-1]]).copy()          # the batch predict_full runs (the crop and its mirror)
    n_params = (pred.net.n_params if pred.backend == "numpy"
                else sum(p.numel() for p in pred.model.parameters()))
    load0 = os.getloadavg()[0]
    # each timed function is run in turn, run by run, so a busy machine slows all alike
    fns = {}
    for b, p in preds.items():
        fns[f"{b} predict_full"] = (lambda p=p: p.predict_full(rgba))
        fns[f"{b} network (batch 2)"] = (lambda p=p: p.predict_normalised(xs, aux=True))
    fns["contact-line heuristic"] = lambda: contact_line_height(rgba[..., 3])
    res = timed_alternating(fns, a.runs)
    lib = []
    if "torch" in preds:
        import torch
        lib.append(f"torch {torch.__version__} ({preds['torch'].device.type})")
    if "numpy" in preds:
        lib.append(f"numpy {np.__version__}, BLAS threads via {height_net.blas_info()}")
    print(f"machine: {cpu_model()}; {'; '.join(lib)}; network threads {a.threads or 'library default'}")
    print(f"model: {a.weights} ({n_params} parameters, runs at {pred.size}^2)")
    print(f"input {a.size}x{a.size}{' on a ' + a.canvas + ' canvas' if a.canvas else ''}, median wall ms (min wall) "
          f"[median CPU ms] of {a.runs} runs, alternating; "
          f"load average {load0:.1f} before, {os.getloadavg()[0]:.1f} after:")
    for name, (med, mn, cpu) in res.items():
        note = " (pinned, foot snap and confidence as the checkpoint says)" if name.endswith("predict_full") else ""
        print(f"  {name:28s} {med:7.1f} ms ({mn:.1f}) [{cpu:.1f}]{note}")
    if len(preds) == 2:
        rn, rt = res["numpy predict_full"], res["torch predict_full"]
        nn_, nt = res["numpy network (batch 2)"], res["torch network (batch 2)"]
        print(f"  numpy / torch: predict_full {rn[0] / rt[0]:.2f} (CPU {rn[2] / rt[2]:.2f}), "
              f"network {nn_[0] / nt[0]:.2f} (CPU {nn_[2] / nt[2]:.2f})")
        on, ot = preds["numpy"].predict_full(rgba), preds["torch"].predict_full(rgba)
        print(f"  largest |numpy - torch|: height {np.abs(on['height'] - ot['height']).max():.2e} px, "
              f"confidence {abs(on['confidence'] - ot['confidence']):.1e}, signal "
              f"{abs(on['signal'] - ot['signal']):.1e}, auto's choice {'same' if on['use_learned'] == ot['use_learned'] else 'DIFFERENT'}")
    if a.own_size:
        ts = {"shipped": [], "own": []}
        keep = pred.work_side, pred.signal_side

        def own():
            pred.work_side, pred.signal_side = None, None
            try:
                pred.predict_full(rgba)
            finally:
                pred.work_side, pred.signal_side = keep
        own()
        for _ in range(a.runs):
            for name, fn in (("shipped", lambda: pred.predict_full(rgba)), ("own", own)):
                t0 = time.perf_counter()
                fn()
                ts[name].append(1e3 * (time.perf_counter() - t0))
        s_, o_ = statistics.median(ts["shipped"]), statistics.median(ts["own"])
        print(f"  {pred.backend}, alternating, {a.runs} runs each: shipped predict_full {s_:.1f} ms, at its own "
              f"size (before the fifth session) {o_:.1f} ms; ratio {s_ / o_:.2f}")
    if a.baseline:
        base = LearnedHeightPredictor(a.baseline, threads=a.threads or None, backend=pred.backend)
        b = timed(lambda: base.predict_full(rgba), a.runs)
        whole = res[f"{pred.backend} predict_full"]
        print(f"  baseline {a.baseline} predict_full {b[0]:7.1f} ms ({b[1]:.1f}) [{b[2]:.1f}]; "
              f"ratio {whole[0] / b[0]:.2f}")
    w = pathlib.Path(a.weights).stat().st_size
    print(f"weights {w / 1e6:.2f} MB (goal <= 20 MB: {'met' if w <= 20e6 else 'missed'})")
    if a.size == 256:
        for b in preds:
            whole = res[f"{b} predict_full"]
            print(f"goal <= 30 ms (wall, one thread, quiet machine), {b}: {'met' if whole[0] <= 30 else 'missed'} "
                  f"here (CPU {whole[2]:.1f} ms)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
