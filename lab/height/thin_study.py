"""Thin parts of large cutouts: the learned height's fill for the pixels the work
size loses (docs/height-record.md, "Rules fixed before measuring: thin parts of large
cutouts" and "Measured: thin parts").

    nice -n 10 python -m pixgraph_lab.height.thin_study generate --n 30 --out data/thin
    nice -n 10 python -m pixgraph_lab.height.thin_study measure --heights data/thin --out runs/thin_study

``generate`` (resumable: existing files are kept) renders ``make_thin_sample(i)``:
an object of the validation split's procedural categories (person, animal,
furniture, product, vehicle; ``categories.make_object``) standing upright, 0.6-0.9
of a 3072^2 image high, with 1-3 thin rods added before rendering (``ROD_KINDS``:
*held*, *antenna*, *stand*), each 1.5-4 px across at its depth, rendered with the
generator's looks and matting (``real.render_real``); heights exact (float32),
sample ``i`` from ``default_rng([seed, 24, i])``; plus ``stick_figure()`` (the
review's case, procedural, exact heights). ``measure`` runs ``predict_full``'s
work-size path with each fill of ``FILLS`` and reports per
sample and pooled the MAE over the lost pixels and over the whole cutout, the
paired bootstrap bounds against ``none`` and the time ratio (the rule's verdict).
``ordinary`` (not the rule's) checks the shipped fill on cutouts without added thin
parts: 256^2 samples enlarged 4x and 8x as ``scale_study`` does.

    nice -n 10 python -m pixgraph_lab.height.thin_study ordinary \\
        --heights data/hreal/val_fresh --limit 60 --out runs/thin_ordinary
"""
from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np

CATS = ("person", "animal", "furniture", "product", "vehicle")
ROD_KINDS = ("held", "antenna", "stand")
RES = 3072


def _rod_ends(kind: str, V: np.ndarray, rng):
    """(p, q): a thin rod of ``kind`` in the object's frame (y up, resting on 0; module doc)."""
    ht = float(V[:, 1].max())
    y = V[:, 1] / ht
    if kind == "held":
        cand = np.nonzero((y >= 0.3) & (y <= 0.8))[0]
        ang, length = math.radians(rng.uniform(0, 30)), rng.uniform(0.2, 0.5) * ht
    elif kind == "antenna":
        cand = np.nonzero(y >= 0.9)[0]
        ang, length = math.radians(rng.uniform(0, 15)), rng.uniform(0.1, 0.4) * ht
    else:                                         # stand: from the object down to the ground
        cand = np.nonzero((y >= 0.2) & (y <= 0.6))[0]
        ang, length = 0.0, 0.0
    if len(cand) == 0:
        cand = np.arange(len(V))
    p = V[cand[rng.integers(len(cand))]].copy()
    az = rng.uniform(0, 2 * math.pi)
    if kind == "stand":
        off = rng.uniform(0, 0.1) * ht
        q = p + np.array([off * math.cos(az), -p[1], off * math.sin(az)])
    else:
        q = p + length * np.array([math.sin(ang) * math.cos(az), math.cos(ang), math.sin(ang) * math.sin(az)])
    return p, q


def _place_large(camera, V, rng, frac=(0.6, 0.9)):
    """(camera, P, x, D) with the object ``V`` ``frac`` of the image high (like
    ``generate._place``: a depth ``D``, a lateral offset ``x`` and the horizon from
    where its foot lands), or None when 50 tries do not fit it in the image."""
    import dataclasses
    W, H, f = camera.width, camera.height, camera.focal
    ht, reach = float(V[:, 1].max()), 0.3 + float(np.abs(V[:, [0, 2]]).max())
    for _ in range(50):
        share, across, foot = rng.uniform((frac[0], 0.4, 0.93), (frac[1], 0.6, 0.98))
        D = max(f * ht / (share * H), reach)
        x = (across * W - W / 2) * D / f
        cam = dataclasses.replace(camera, horizon=float(foot * H - f * camera.cam_height / D))
        P = V + np.array([x, 0.0, -D])
        uvh, depth = cam.project(P)
        u, v = uvh[:, 0], uvh[:, 1]
        if min(depth.min() - 0.1, u.min() - 3, W - 3 - u.max(), v.min() - 3, H - 3 - v.max()) > 0:
            return cam, P, x, D
    return None


def make_thin_sample(index: int, seed: int = 24, res: int = RES):
    """One sample (arrays, meta): module doc."""
    from pixgraph_lab.datagen.categories import cylinder, make_object
    from pixgraph_nodes.ops.camera import Camera

    from .real import pose_real, render_real
    rng = np.random.default_rng([seed, 24, index])
    t0 = time.perf_counter()
    for tries in range(1, 100):
        cat = str(rng.choice(CATS))
        V0, F0, slots0, names, kind = make_object(cat, rng)
        V = pose_real(V0, "upright", rng)
        kinds = [str(k) for k in rng.choice(ROD_KINDS, size=int(rng.integers(1, 4)))]
        ends = [_rod_ends(k, V, rng) for k in kinds]
        diam = rng.uniform(1.5, 4.0, len(kinds))           # [px] at the rod's depth
        allv = np.concatenate([V] + [np.stack(e) for e in ends])
        cam = Camera(res, res, hfov=float(rng.uniform(30, 70)), horizon=0.0,
                     cam_height=float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))))
        placed = _place_large(cam, allv, rng)
        if placed is None:
            continue
        cam, _, x, D = placed
        Vs, Fs, Ss, off = [V], [F0], [slots0], len(V)
        slot = len(names)
        for (p, q), dp in zip(ends, diam):
            depth = D - 0.5 * (p[2] + q[2])
            m = cylinder(p, q, 0.5 * dp * depth / cam.focal, 8)
            Vs.append(np.asarray(m.vertices, np.float64))
            Fs.append(np.asarray(m.faces, np.int64) + off)
            Ss.append(np.full(len(m.faces), slot, np.int64))
            off += len(m.vertices)
        PV = np.concatenate(Vs) + np.array([x, 0.0, -D])
        rgb, alpha, mask, height = render_real(cam, PV, np.concatenate(Fs), np.concatenate(Ss),
                                               list(names) + ["rod"], rng)
        if (alpha[0] > 0).any() or (alpha[-1] > 0).any() or (alpha[:, 0] > 0).any() or (alpha[:, -1] > 0).any():
            continue
        from .generate import srgb_encode
        srgb8 = np.round(srgb_encode(rgb) * 255).astype(np.uint8)
        meta = {"index": index, "rng": [seed, 24, index], "category": cat, "object": kind, "rods": kinds,
                "rod_px": [float(d) for d in diam], "camera": cam.to_dict(), "mask_px": int(mask.sum()),
                "tries": tries, "seconds": time.perf_counter() - t0}
        return {"rgb": srgb8, "alpha": np.round(alpha * 255).astype(np.uint8), "mask": mask,
                "height": height.astype(np.float32)}, meta
    raise RuntimeError(f"thin sample {index}: no valid scene in 100 tries")


def stick_figure(H: int = 2600, W: int = 1600, fig: int = 2400, stick: int = 1000, width: int = 3):
    """The review's case: a flat upright figure ``fig`` px tall standing on row H - 40, holding
    a ``width``-px vertical stick at its side that rises ``stick`` px above the hand.

    Returns (premultiplied linear RGBA float32 (H, W, 4), true height [px] float32, mask,
    the stick's mask): everything upright in one plane on the ground, so the true pixel
    height is the contact line's, ``v_contact - v`` with ``v_contact = H - 40`` (the bottom
    edge of the lowest row) and ``v = row + 0.5``."""
    r_foot = H - 40                                # the first row below the figure
    top = r_foot - fig
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32) + 0.5
    cx = W / 2
    s = fig / 2400.0
    head = (xx - cx) ** 2 + (yy - (top + 160 * s)) ** 2 <= (160 * s) ** 2
    body = (np.abs(xx - cx) <= 260 * s) & (yy >= top + 300 * s) & (yy <= top + 1300 * s)
    legs = ((np.abs(xx - (cx - 140 * s)) <= 90 * s) | (np.abs(xx - (cx + 140 * s)) <= 90 * s)) \
        & (yy >= top + 1300 * s) & (yy < r_foot)
    arm = (xx >= cx + 260 * s) & (xx <= cx + 520 * s) & (np.abs(yy - (top + 800 * s)) <= 50 * s)
    hand_x = int(cx + 520 * s) - 4
    hand_r = int(top + 800 * s)
    stk = (xx >= hand_x) & (xx < hand_x + width) & (yy >= hand_r - stick) & (yy <= hand_r)
    mask = head | body | legs | arm | stk
    true = np.where(mask, r_foot - yy, 0.0).astype(np.float32)
    shade = 0.25 + 0.35 * (yy / H) + 0.1 * np.cos(xx / 90.0)
    rgb = np.stack([shade * 0.8, shade * 0.6, shade * 0.5], -1) * mask[..., None]
    rgba = np.concatenate([rgb, mask[..., None].astype(np.float32)], -1).astype(np.float32)
    return rgba, true, mask, stk & ~(head | body | legs | arm)


def _save(path, arrays, meta):
    tmp = path + ".tmp.npz"
    np.savez_compressed(tmp, meta=np.array(json.dumps(meta)), **arrays)
    os.replace(tmp, path)


def generate(n: int, out: str, seed: int = 24, res: int = RES, start: int = 0) -> None:
    os.makedirs(out, exist_ok=True)
    for i in range(start, n):
        path = os.path.join(out, f"{i:05d}.npz")
        if os.path.exists(path):
            continue
        arrays, meta = make_thin_sample(i, seed, res)
        _save(path, arrays, meta)
        print(f"{path}: {meta['object']} rods {meta['rods']} {['%.1f' % d for d in meta['rod_px']]} px, "
              f"{meta['seconds']:.1f} s", flush=True)


def lost_pixels(predictor, rgba: np.ndarray, threshold: float = 0.5) -> np.ndarray:
    """The full-size pixels of ``rgba``'s cutout that the work-size path finds no
    work-size mask pixel for, bool (H, W): ``predict_at_work_size``'s ``thin_lost``
    (``masked_resize``'s ``lost``); all False when the cutout is predicted at its own size."""
    from pixgraph_nodes.ops.height_work_size import predict_at_work_size
    r = predict_at_work_size(predictor, rgba, threshold, work_side=predictor.work_side, thin_fill="none")
    return r.get("thin_lost", np.zeros(rgba.shape[:2], bool))


def _samples(folders):
    """(name, rgba, true height, true mask, meta) of every sample of ``folders`` and the stick figure."""
    from .evaluate import height_files, read_height_sample
    for d in folders:
        for f in height_files(d):
            meta, rgba, true, mask = read_height_sample(f)
            yield f"{os.path.basename(d.rstrip('/'))}/{meta['index']:05d}", rgba, true, mask.astype(bool), meta
    rgba, true, mask, _ = stick_figure()
    yield "stick_figure", rgba, true, mask, {"object": "stick figure", "rods": ["held"], "rod_px": [3.0]}


def attached_fill(height: np.ndarray, mask: np.ndarray, lost: np.ndarray, heuristic: np.ndarray,
                  ground: bool = False) -> np.ndarray:
    """A candidate fill of the rule (``FILLS``; lost to ``contact``): each 8-connected
    component of lost pixels is taken to be an upright part standing where what it is
    attached to stands: the covered mask pixels 8-adjacent to it imply a contact row
    ``row + height`` each; their mean ``v`` gives the part ``max(0, v - row)``; a
    component with no covered neighbour takes ``heuristic``. ``ground``
    (``attached_ground``): a component reaching the silhouette's two lowest rows stands
    on the ground itself: 0 at its lowest pixel's bottom edge, +1 px per row up."""
    from pixgraph_nodes.ops.resample import nonzero_box
    from scipy import ndimage
    H, W = mask.shape
    r0, r1, c0, c1 = nonzero_box(lost)
    lo = lost[r0:r1, c0:c1]
    lab, n = ndimage.label(lo, structure=np.ones((3, 3), bool))
    lr, lc = np.nonzero(lo)
    lr, lc = lr + r0, lc + c0                           # the lost pixels (full-size rows, columns)
    kl = lab[lr - r0, lc - c0]
    # their covered 8-neighbours, each counted once per component
    nb_k, nb_i = [], []
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            rr, cc = lr + dr, lc + dc
            ok = (rr >= 0) & (rr < H) & (cc >= 0) & (cc < W)
            rr, cc, k = rr[ok], cc[ok], kl[ok]
            ok = mask[rr, cc] & ~lost[rr, cc]
            nb_k.append(k[ok])
            nb_i.append(rr[ok] * W + cc[ok])
    pairs = np.unique(np.stack([np.concatenate(nb_k), np.concatenate(nb_i)]).astype(np.int64), axis=1)
    k, idx = pairs
    implied = (idx // W).astype(np.float64) + height.reshape(-1)[idx]      # the contact row they imply
    cnt = np.bincount(k, minlength=n + 1)
    level = np.bincount(k, weights=implied, minlength=n + 1) / np.maximum(cnt, 1)
    row = lr.astype(np.float64)
    val = level[kl] - row
    if ground:
        low = np.array([-1] + [sl[0].stop - 1 + r0 for sl in ndimage.find_objects(lab)], np.float64)
        bottom = float(np.nonzero(mask.any(1))[0].max())
        own = low[kl] >= bottom - 1
        val = np.where(own, low[kl] + 0.5 - row, val)
        cnt[1:][low[1:] >= bottom - 1] = 1       # standing on the ground: no fall back to the contact line
    val = np.where(cnt[kl] > 0, val, heuristic[lr, lc])
    height[lr, lc] = np.maximum(val, 0.0)
    return height




#: the rule's candidates: ``height_work_size.fill_thin``'s ``how`` (``contact`` shipped)
FILLS = {"none": "none", "contact": "contact", "attached": attached_fill,
         "attached_ground": lambda h, m, lost, heur: attached_fill(h, m, lost, heur, ground=True)}


def measure(folders, out: str, weights: str | None = None, min_lost: int = 50) -> list[str]:
    """The rule's numbers (module doc); writes ``out/thin.csv`` and ``out/thin_study.md``."""
    import torch
    torch.set_num_threads(1)
    from pixgraph_nodes.ops.height_work_size import predict_at_work_size
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor

    from .evaluate import _write, write_report
    from .scale_study import upper_bound
    pred = LearnedHeightPredictor(weights or WEIGHTS)
    rows = []
    for n, (name, rgba, true, tmask, meta) in enumerate(_samples(folders)):
        lost = lost_pixels(pred, rgba) & tmask
        if n == 0:                     # warm up (first-call costs) before anything is timed
            predict_at_work_size(pred, rgba, 0.5, "ground", 0.0, pred.work_side, False, "none")
        row = {"sample": name, "object": meta.get("object"), "rods": "+".join(meta.get("rods", [])),
               "rod_px": "/".join(f"{d:.1f}" for d in meta.get("rod_px", [])),
               "side": int(max(np.ptp(np.nonzero(tmask)[0]), np.ptp(np.nonzero(tmask)[1])) + 1),
               "cutout_px": int(tmask.sum()), "lost_px": int(lost.sum())}
        maps = {}
        names = list(FILLS)
        order = names[n % len(names):] + names[:n % len(names)]
        for how in order:
            t0, c0 = time.perf_counter(), time.process_time()
            r = predict_at_work_size(pred, rgba, 0.5, "ground", 0.0, pred.work_side, False, FILLS[how])
            row[f"s_{how}"] = time.perf_counter() - t0
            row[f"cpu_{how}"] = time.process_time() - c0
            h = r["height"]
            maps[how] = h
            row[f"mae_{how}"] = float(np.abs(h[tmask] - true[tmask]).mean())
            row[f"lost_mae_{how}"] = float(np.abs(h[lost] - true[lost]).mean()) if lost.any() else float("nan")
            row["work_scale"] = float(r.get("work_scale", 1.0))
        row["identical"] = int(all(np.array_equal(maps[h], maps["none"]) for h in FILLS))
        rows.append(row)
        print(name, {k: (round(v, 3) if isinstance(v, float) else v) for k, v in row.items()}, flush=True)
    os.makedirs(out, exist_ok=True)
    _write(os.path.join(out, "thin.csv"), rows)
    use = [r for r in rows if r["lost_px"] >= min_lost]
    free = [r for r in rows if r["lost_px"] == 0]
    lines = [f"load average at the end {os.getloadavg()[0]:.2f} (times are wall seconds; CPU seconds in "
             "thin.csv)", "", f"weights {weights or WEIGHTS}; {len(rows)} samples ({', '.join(folders)} + the stick figure); "
             f"{len(use)} with at least {min_lost} lost pixels; {len(free)} with none (maps identical for every "
             f"fill: {sum(r['identical'] for r in free)} of {len(free)})", "",
             "| fill | MAE lost px | diff vs none [95 % bound] | MAE whole cutout | diff vs none [95 % bound] | "
             "median time ratio | met |", "|---|---|---|---|---|---|---|"]
    base_whole = float(np.mean([r["mae_none"] for r in use]))
    best, verdicts = None, {}
    for how in FILLS:
        lm = float(np.mean([r[f"lost_mae_{how}"] for r in use]))
        wm = float(np.mean([r[f"mae_{how}"] for r in use]))
        dl = [r[f"lost_mae_{how}"] - r["lost_mae_none"] for r in use]
        dw = [r[f"mae_{how}"] - r["mae_none"] for r in use]
        ubl, ubw = upper_bound(dl), upper_bound(dw)
        tr = float(np.median([r[f"s_{how}"] / r["s_none"] for r in use]))
        met = how != "none" and ubl < 0 and ubw <= 0.005 * base_whole and tr <= 1.10
        verdicts[how] = met
        if met and (best is None or lm < best[1]):
            best = (how, lm)
        lines.append(f"| {how} | {lm:.1f} | {np.mean(dl):+.1f} [{ubl:+.1f}] | {wm:.2f} | {np.mean(dw):+.3f} "
                     f"[{ubw:+.3f}; margin {0.005 * base_whole:.3f}] | {tr:.3f} | "
                     f"{'-' if how == 'none' else ('yes' if met else 'no')} |")
    lines += ["", "Per sample (MAE over the lost pixels [px]; none / contact / attached / attached_ground):", "",
              "| sample | object | rods (px across) | side px | f | lost px | none | contact | attached | "
              "attached_ground |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['sample']} | {r['object']} | {r['rods']} ({r['rod_px']}) | {r['side']} | "
                     f"{r['work_scale']:.2f} | {r['lost_px']} | "
                     + " | ".join(f"{r[f'lost_mae_{h}']:.1f}" for h in FILLS) + " |")
    lines += ["", f"**ships: {best[0]}**" if best else "**nothing ships**"]
    write_report(out, "thin_study.md", lines)
    return lines


def ordinary(folder: str, out: str, scales=(4, 8), limit: int = 60, weights: str | None = None) -> list[str]:
    """Not the rule's: cutouts without added thin parts (``folder``'s 256^2 samples enlarged
    k times as ``scale_study.enlarge`` does: bilinear RGBA and heights, nearest mask),
    the shipped fill against ``none``: how many pixels are lost, and the MAE over the
    whole cutout [px / k]."""
    import torch
    torch.set_num_threads(1)
    from pixgraph_nodes.ops.height_work_size import THIN_FILL, predict_at_work_size
    from pixgraph_nodes.ops.learned_height import WEIGHTS, LearnedHeightPredictor

    from .evaluate import _write, height_files, read_height_sample, write_report
    from .scale_study import enlarge, upper_bound
    pred = LearnedHeightPredictor(weights or WEIGHTS)
    rows = []
    for f in height_files(folder, limit):
        meta, rgba, true, mask = read_height_sample(f)
        for k in scales:
            big, tb, mb = enlarge(rgba, true, mask, k)
            lost = lost_pixels(pred, big)
            row = {"index": meta["index"], "k": k, "lost_px": int(lost.sum()), "lost_in_true": int((lost & mb).sum())}
            for how in ("none", THIN_FILL):
                h = predict_at_work_size(pred, big, 0.5, "ground", 0.0, pred.work_side, False, how)["height"]
                row[f"mae_{how}"] = float(np.abs(h[mb] - tb[mb]).mean()) / k
            rows.append(row)
    os.makedirs(out, exist_ok=True)
    _write(os.path.join(out, "ordinary.csv"), rows)
    lines = [f"{len(rows) // len(scales)} samples of {folder} enlarged {', '.join(f'{k}x' for k in scales)}; "
             f"fill {THIN_FILL} vs none; MAE over the cutout in px / k", "",
             "| scale | samples with lost px | lost px (median, max) | MAE none | MAE fill | mean diff [95 % bound] |",
             "|---|---|---|---|---|---|"]
    for k in scales:
        rs = [r for r in rows if r["k"] == k]
        d = [r[f"mae_{THIN_FILL}"] - r["mae_none"] for r in rs]
        lp = [r["lost_px"] for r in rs]
        lines.append(f"| {k}x | {sum(x > 0 for x in lp)} of {len(rs)} | {np.median(lp):.0f}, {max(lp)} | "
                     f"{np.mean([r['mae_none'] for r in rs]):.4f} | {np.mean([r[f'mae_{THIN_FILL}'] for r in rs]):.4f} | "
                     f"{np.mean(d):+.4f} [{upper_bound(d):+.4f}] |")
    write_report(out, "ordinary.md", lines)
    return lines


def hairy_figure(H: int = 6000, W: int = 4000, strands: int = 200, seed: int = 0):
    """``stick_figure`` at 6000 x 4000 (24 MP; the figure 5,500 px tall) with ``strands``
    1-2 px lines rising 100-600 px from its head and shoulders (hair, wires): a cutout
    with many lost components, for ``time_fill``. Returns the premultiplied RGBA."""
    rgba, _, mask, _ = stick_figure(H, W, fig=5500, stick=1200, width=3)
    rng = np.random.default_rng(seed)
    rows = np.nonzero(mask.any(1))[0]
    top = int(rows.min())
    for _ in range(strands):
        cands = np.nonzero(mask[top + int(rng.integers(0, 1200))])[0]
        if len(cands) == 0:
            continue
        c, r = int(rng.choice(cands)), top + int(rng.integers(0, 1200))
        length, lean, w = int(rng.integers(100, 600)), rng.uniform(-0.5, 0.5), int(rng.integers(1, 3))
        rr = np.arange(max(r - length, 1), r)
        cc = np.clip((c + lean * (rr - r)).astype(int), 1, W - 3)
        for d in range(w):
            rgba[rr, cc + d] = rgba[r, c] if rgba[r, c, 3] > 0 else (0.3, 0.2, 0.1, 1.0)
    return rgba


def time_fill(runs: int = 5) -> list[str]:
    """Wall and CPU time of ``predict_full``'s work-size path on ``hairy_figure`` (24 MP) with
    the shipped fill and with ``none``, alternating run by run, and of ``masked_resize``
    with and without ``return_lost`` (what a cutout without lost pixels pays)."""
    import torch
    torch.set_num_threads(1)
    from pixgraph_nodes.ops.height_work_size import THIN_FILL, predict_at_work_size, shrink_cutout, work_shape
    from pixgraph_nodes.ops.learned_height import LearnedHeightPredictor, crop_box
    from pixgraph_nodes.ops.upsample import masked_resize
    pred = LearnedHeightPredictor()
    rgba = hairy_figure()
    lost = lost_pixels(pred, rgba)
    mask = rgba[..., 3] > 0.5
    box = crop_box(mask)
    f, shape = work_shape(*mask.shape, box[6], pred.work_side)
    ms = (shrink_cutout(rgba, shape)[..., 3] > 0.5).astype(np.float32)
    lo = np.ones(shape, np.float32)
    jobs = {"fill " + THIN_FILL: lambda: predict_at_work_size(pred, rgba, thin_fill=THIN_FILL),
            "fill none": lambda: predict_at_work_size(pred, rgba, thin_fill="none"),
            "masked_resize, return_lost": lambda: masked_resize(lo, ms, mask, mask.shape, box=box[:4],
                                                                return_lost=True),
            "masked_resize": lambda: masked_resize(lo, ms, mask, mask.shape, box=box[:4])}
    for fn in jobs.values():
        fn()                                          # warm up
    got = {k: [] for k in jobs}
    for _ in range(runs):
        for k, fn in jobs.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            got[k].append((time.perf_counter() - t0, time.process_time() - c0))
    lines = [f"hairy_figure: {rgba.shape[1]}x{rgba.shape[0]}, {int(mask.sum())} cutout px, {int(lost.sum())} lost, "
             f"f {f:.2f}; {runs} runs alternating, load average {os.getloadavg()[0]:.2f}", "",
             "| job | median wall ms | median CPU ms |", "|---|---|---|"]
    for k, v in got.items():
        v = np.array(v) * 1e3
        lines.append(f"| {k} | {np.median(v[:, 0]):.0f} | {np.median(v[:, 1]):.0f} |")
    print("\n".join(lines))
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.thin_study", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("generate")
    g.add_argument("--n", type=int, required=True)
    g.add_argument("--start", type=int, default=0)
    g.add_argument("--seed", type=int, default=24)
    g.add_argument("--res", type=int, default=RES)
    g.add_argument("--out", required=True)
    m = sub.add_parser("measure")
    m.add_argument("--heights", nargs="+", required=True)
    m.add_argument("--weights", default=None)
    m.add_argument("--out", required=True)
    o = sub.add_parser("ordinary")
    o.add_argument("--heights", required=True)
    o.add_argument("--scales", type=int, nargs="+", default=[4, 8])
    o.add_argument("--limit", type=int, default=60)
    o.add_argument("--weights", default=None)
    o.add_argument("--out", required=True)
    t = sub.add_parser("time")
    t.add_argument("--runs", type=int, default=5)
    a = ap.parse_args(argv)
    if a.cmd == "time":
        time_fill(a.runs)
    elif a.cmd == "generate":
        generate(a.n, a.out, a.seed, a.res, a.start)
    elif a.cmd == "ordinary":
        ordinary(a.heights, a.out, a.scales, a.limit, a.weights)
    else:
        measure(a.heights, a.out, a.weights)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
