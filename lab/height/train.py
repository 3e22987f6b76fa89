"""Train the cutout pixel-height U-Net (``pixgraph_nodes.ops.learned_height``).

    python -m pixgraph_lab.height.train --data data/height --out runs/height --minutes 45 --seed 0

Data: ``DATA/train`` and ``DATA/val`` written by ``pixgraph_lab.height.generate``
(objects disjoint). Every sample is cropped around its cutout and resized to
``--size`` once (``prepare``), cached in ``DATA/cache_{split}_{size}.npz``.

Loss: the mean over mask pixels (weight = the crop's resized mask) of
|prediction - height / bh| plus 0.5 x the same for the horizontal and vertical
differences of neighbouring pixels (so the slopes of the height map, which set
where a shadow falls, are learned, not only its mean), where bh is the
cutout's bounding-box height [px] (module doc of learned_height).

Augmentation (per sample, each step): horizontal flip (a mirrored photo has the
same heights), zoom 0.8-1.2 and shift up to 8 % of the crop (the targets and the
heuristic / row channels are in units of bh, so they are unchanged), colour
gains 0.6-1.4 per channel, channel permutation, grey 20 % of the time. With
``--stretch A`` (> 1) half the samples also have one image axis (x or y, at
random) shrunk by a factor drawn log-uniformly from [1, A]: a squatter or
slimmer variant of the object with exact targets, since a vertical stretch
scales the heights and bh alike and a horizontal one neither (the heuristic's
and the row channel are unchanged for the same reason).

Resumable: ``OUT/last.pt`` (model, optimiser, step, RNG states, curve) is
written every ``--checkpoint-minutes``; a new run with the same ``--out`` resumes.
``OUT/best.pt`` keeps the lowest validation MAE; ``OUT/curve.csv`` and
``OUT/curve.png`` the validation curve. Uses CUDA when available.
"""
from __future__ import annotations

import argparse
import csv
import glob
import json
import os
import sys
import time

import numpy as np


def load_split(data: str, split: str, size: int, limit: int | None = None):
    """Arrays x (N, 6, S, S) float16, target (N, S, S) float16, weight (N, S, S) uint8-ish,
    bh (N,), meta list — cached."""
    from pixgraph_nodes.ops.learned_height import prepare
    files = sorted(glob.glob(os.path.join(data, split, "[0-9]" * 5 + ".npz")))
    if limit:
        files = files[:limit]
    cache = os.path.join(data, f"cache_{split}_{size}.npz")
    names = [os.path.basename(f) for f in files]
    have = {}
    if os.path.exists(cache):
        with np.load(cache, allow_pickle=False) as z:
            if int(z["n"]) == len(files) and ("names" not in z or list(z["names"]) == names):
                return {k: z[k] for k in ("x", "t", "w", "bh")} | {"meta": json.loads(str(z["meta"]))}
            if "names" in z:    # a grown snapshot: keep the crops already made, prepare the new files
                old_meta = json.loads(str(z["meta"]))
                zx, zt, zw, zb = z["x"], z["t"], z["w"], z["bh"]
                have = {str(nm): (zx[i], zt[i], zw[i], zb[i], old_meta[i]) for i, nm in enumerate(z["names"])}
    X, T, Wt, BH, M = [], [], [], [], []
    for f, nm in zip(files, names):
        if nm in have:
            x, t, w, bh, meta = have[nm]
            X.append(x); T.append(t); Wt.append(w); BH.append(bh); M.append(meta)
            continue
        with np.load(f, allow_pickle=False) as z:
            rgb = z["rgb"].astype(np.float32) / 255
            a = z["alpha"].astype(np.float32) / 255
            h = z["height"].astype(np.float32)
            meta = json.loads(str(z["meta"]))
            mask = z["mask"]
        # the stored mask is the centre ray; prepare thresholds alpha at 0.5
        x, box, bh, t, w = prepare(rgb, a, size, height=np.where(mask, h, 0.0))
        X.append(x.astype(np.float16)); T.append(t.astype(np.float16)); Wt.append(w.astype(np.float16))
        BH.append(bh); M.append(meta)
    out = {"x": np.stack(X), "t": np.stack(T), "w": np.stack(Wt), "bh": np.array(BH, np.float32), "meta": M}
    tmp = cache + ".tmp.npz"
    np.savez(tmp, x=out["x"], t=out["t"], w=out["w"], bh=out["bh"], n=len(files), meta=json.dumps(M),
             names=np.array(names))
    os.replace(tmp, cache)
    return out


def load_splits(data: str, splits, size: int, limit: int | None = None):
    """``load_split`` of several sub-folders, concatenated (``limit`` applies to each)."""
    parts = [load_split(data, s, size, limit) for s in splits]
    if len(parts) == 1:
        return parts[0]
    out = {k: np.concatenate([p[k] for p in parts]) for k in ("x", "t", "w", "bh")}
    out["meta"] = [m for p in parts for m in p["meta"]]
    return out


def augment(x, t, w, gen, stretch: float = 1.0):
    """Random flips / zoom / shift / colour and, with ``stretch`` > 1, one axis
    shrunk (module doc) on a batch (torch tensors)."""
    import torch
    import torch.nn.functional as F
    B = x.shape[0]
    dev = x.device
    flip = torch.rand(B, generator=gen, device="cpu") < 0.5
    s = torch.empty(B).uniform_(0.8, 1.2, generator=gen)
    tx = torch.empty(B).uniform_(-0.08, 0.08, generator=gen)
    ty = torch.empty(B).uniform_(-0.08, 0.08, generator=gen)
    sx = torch.where(flip, -1.0, 1.0) / s
    sy = 1.0 / s
    if stretch > 1.0:
        # drawn only when asked, so the default run consumes the generator as before
        on = torch.rand(B, generator=gen) < 0.5
        k = torch.exp(torch.empty(B).uniform_(0.0, float(np.log(stretch)), generator=gen))
        k = torch.where(on, k, torch.ones_like(k))
        along_x = torch.rand(B, generator=gen) < 0.5
        # the grid reads k times further out along that axis: the content shrinks by k
        sx = sx * torch.where(along_x, k, torch.ones_like(k))
        sy = sy * torch.where(along_x, torch.ones_like(k), k)
    theta = torch.zeros(B, 2, 3)
    theta[:, 0, 0], theta[:, 1, 1] = sx, sy
    theta[:, 0, 2], theta[:, 1, 2] = tx, ty
    grid = F.affine_grid(theta.to(dev), list(x.shape), align_corners=False)
    # t is normalised (height / bh where w > 0): resample t w and w, then divide
    full = torch.cat([x, (t * w)[:, None], w[:, None]], 1)
    out = F.grid_sample(full, grid, mode="bilinear", padding_mode="zeros", align_corners=False)
    # the row channel is a vertical ramp in bh units: evaluate it at the source rows
    S = x.shape[-1]
    y0, y1 = 1.0 / S - 1.0, 1.0 - 1.0 / S
    r0, r1 = x[:, 5, 0, 0], x[:, 5, -1, 0]
    b = (r1 - r0) / (y1 - y0)
    out[:, 5] = (r0 - b * y0)[:, None, None] + b[:, None, None] * grid[..., 1]
    x2, w2 = out[:, :6], out[:, 7]
    t2 = out[:, 6] / torch.clamp(w2, min=1e-6)
    t2 = torch.where(w2 > 1e-3, t2, torch.zeros_like(t2))
    gains = torch.empty(B, 3, 1, 1).uniform_(0.6, 1.4, generator=gen).to(dev)
    col = x2[:, :3] * gains
    perm = torch.stack([torch.randperm(3, generator=gen) for _ in range(B)]).to(dev)
    col = torch.gather(col, 1, perm[:, :, None, None].expand_as(col))
    grey = (torch.rand(B, generator=gen) < 0.2).to(dev)[:, None, None, None]
    col = torch.where(grey, col.mean(1, keepdim=True).expand_as(col), col)
    col = torch.minimum(col, x2[:, 3:4])             # premultiplied: colour <= alpha
    return torch.cat([col, x2[:, 3:]], 1), t2, w2


def contact_pin(p, x, band: float = 1.5):
    """``p`` shifted per sample so its mean over the crop's contact pixels (alpha >
    0.5 and within ``band`` crop pixels of the cutout's bottom edge, read from the
    row channel) is 0: the training-time twin of ``learned_height.pin_contact``."""
    import torch
    step = (x[:, 5, 0, 0] - x[:, 5, 1, 0]).abs().clamp(min=1e-6)[:, None, None]
    c = ((x[:, 3] > 0.5) & (x[:, 5] < band * step)).float()
    n = c.sum((1, 2))
    off = torch.where(n > 0, (p * c).sum((1, 2)) / n.clamp(min=1), torch.zeros_like(n))
    return p - off[:, None, None]


def error_head_loss(e, p, x, t, w, floor: float = 0.005):
    """L1 between the error heads (log |error| / bh) and the actual log errors of the
    (pinned, detached) learned height and of the contact-line channel, mask-weighted."""
    import torch
    tl = torch.log((p.detach() - t).abs() + floor)
    th = torch.log((contact_pin(x[:, 4], x) - t).abs() + floor)
    ws = w.sum().clamp(min=1.0)
    return ((w * (e[:, 0] - tl).abs()).sum() + (w * (e[:, 1] - th).abs()).sum()) / ws


def masked_loss(p, t, w):
    wsum = w.sum().clamp(min=1.0)
    l0 = (w * (p - t).abs()).sum() / wsum
    wx = w[:, :, 1:] * w[:, :, :-1]
    wy = w[:, 1:] * w[:, :-1]
    lx = (wx * ((p[:, :, 1:] - p[:, :, :-1]) - (t[:, :, 1:] - t[:, :, :-1])).abs()).sum() / wx.sum().clamp(min=1)
    ly = (wy * ((p[:, 1:] - p[:, :-1]) - (t[:, 1:] - t[:, :-1])).abs()).sum() / wy.sum().clamp(min=1)
    return l0 + 0.5 * (lx + ly) * p.shape[-1] / 32.0


def evaluate(model, val, device, batch=32):
    """Validation MAE of height/bh, in crop pixels x bh ~ px of the original, and of the
    heuristic (channel 4), mean over samples of the per-sample mask-weighted mean."""
    import torch

    from pixgraph_nodes.ops.learned_height import split_output
    model.eval()
    maes, heur = [], []
    with torch.inference_mode():
        for i in range(0, len(val["x"]), batch):
            x = torch.from_numpy(val["x"][i:i + batch].astype(np.float32)).to(device)
            t = torch.from_numpy(val["t"][i:i + batch].astype(np.float32)).to(device)
            w = torch.from_numpy(val["w"][i:i + batch].astype(np.float32)).to(device)
            p = contact_pin(split_output(model(x))[0], x)
            bh = torch.from_numpy(val["bh"][i:i + batch]).to(device)
            ws = w.sum((1, 2)).clamp(min=1)
            maes.append(((w * (p - t).abs()).sum((1, 2)) / ws * bh).cpu().numpy())
            heur.append(((w * (x[:, 4] - t).abs()).sum((1, 2)) / ws * bh).cpu().numpy())
    model.train()
    return float(np.concatenate(maes).mean()), float(np.concatenate(heur).mean())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.train", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--base", type=int, default=8)
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--batch", type=int, default=16)
    ap.add_argument("--lr", type=float, default=2e-3)
    ap.add_argument("--steps", type=int, default=2500, help="total steps (cosine schedule length)")
    ap.add_argument("--minutes", type=float, default=1e9, help="stop (with a checkpoint) after this long")
    ap.add_argument("--val-every", type=int, default=250)
    ap.add_argument("--checkpoint-minutes", type=float, default=3.0)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--limit", type=int, default=None, help="use at most this many training samples")
    ap.add_argument("--train-splits", default="train",
                    help="comma-separated sub-folders of --data to train on, e.g. train,train_bench "
                         "(train_bench: pixgraph_lab.height.from_benchmark)")
    ap.add_argument("--val-splits", default="val", help="comma-separated validation sub-folders")
    ap.add_argument("--outputs", type=int, choices=(1, 3), default=1,
                    help="3: also the two confidence heads (learned_height.build_model)")
    ap.add_argument("--init", default=None,
                    help="start from this checkpoint's weights (e.g. the shipped one; a 1-output "
                         "head is copied into the height channel of a 3-output one)")
    ap.add_argument("--widen-from", default=None,
                    help="start from this narrower checkpoint widened to --base (lab/height/widen.py: the same "
                         "function, copies broken by --widen-noise)")
    ap.add_argument("--widen-noise", type=float, default=0.01)
    ap.add_argument("--stretch", type=float, default=1.0,
                    help="> 1: half the samples get one axis shrunk by a factor in [1, STRETCH] (module doc)")
    ap.add_argument("--pin", action="store_true",
                    help="train the contact-pinned height (the contact pixels' mean shifted to 0, "
                         "as predict does with contact='ground')")
    a = ap.parse_args(argv)
    if a.stretch < 1.0:
        ap.error(f"--stretch {a.stretch}: a factor >= 1 (1 = off), the most an axis is shrunk by")
    import torch
    torch.set_num_threads(a.threads)
    torch.manual_seed(a.seed)
    device = torch.device("cuda" if torch.cuda.is_available() else "cpu")
    from pixgraph_nodes.ops.learned_height import build_model, split_output
    os.makedirs(a.out, exist_ok=True)
    t_load = time.perf_counter()
    train = load_splits(a.data, a.train_splits.split(","), a.size, a.limit)
    val = load_splits(a.data, a.val_splits.split(","), a.size)
    print(f"data: {len(train['x'])} train, {len(val['x'])} val ({time.perf_counter() - t_load:.0f} s to load)",
          flush=True)
    model = build_model(a.base, a.levels, a.outputs).to(device)
    if a.init and not os.path.exists(os.path.join(a.out, "last.pt")):
        ck0 = torch.load(a.init, map_location="cpu", weights_only=True)
        sd = {k: v.float() for k, v in ck0["model"].items()}
        own = model.state_dict()
        for k in ("head.weight", "head.bias"):
            if k in sd and sd[k].shape != own[k].shape:
                v = torch.zeros_like(own[k])
                v[:1] = sd[k]
                if k == "head.bias":
                    v[1:] = float(np.log(0.05))
                sd[k] = v
        model.load_state_dict(sd)
        print(f"initialised from {a.init}", flush=True)
    if a.widen_from and not os.path.exists(os.path.join(a.out, "last.pt")):
        from .widen import widen_state
        ck0 = torch.load(a.widen_from, map_location="cpu", weights_only=True)
        cfg0 = json.loads(ck0["config"]) if isinstance(ck0["config"], str) else ck0["config"]
        if (int(cfg0["levels"]), int(cfg0.get("outputs", 1))) != (a.levels, a.outputs):
            raise SystemExit(f"--widen-from {a.widen_from}: levels/outputs {cfg0['levels']}/{cfg0.get('outputs', 1)} "
                             f"differ from --levels {a.levels} --outputs {a.outputs}")
        model.load_state_dict(widen_state(ck0["model"], int(cfg0["base"]), a.base, a.levels, a.widen_noise, a.seed))
        print(f"widened {a.widen_from} from base {cfg0['base']} to {a.base}", flush=True)
    opt = torch.optim.AdamW(model.parameters(), lr=a.lr, weight_decay=1e-4)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=a.lr, total_steps=a.steps,
                                                pct_start=min(0.5, max(0.05, 3.0 / a.steps)))
    gen = torch.Generator().manual_seed(a.seed)
    rng = np.random.default_rng(a.seed)
    config = {"size": a.size, "base": a.base, "levels": a.levels, "in_channels": 6, "outputs": a.outputs,
              "pin": bool(a.pin), "init": a.init or a.widen_from,
              "target": "pixel height / cutout bounding-box height"}
    if a.stretch > 1.0:
        config["stretch"] = a.stretch
    state = {"step": 0, "curve": [], "best": float("inf"), "seconds": 0.0}
    last = os.path.join(a.out, "last.pt")
    if os.path.exists(last):
        ck = torch.load(last, map_location=device, weights_only=False)
        model.load_state_dict(ck["model"]); opt.load_state_dict(ck["opt"]); sched.load_state_dict(ck["sched"])
        gen.set_state(ck["gen"]); rng.bit_generator.state = ck["rng"]; state = ck["state"]
        print(f"resumed at step {state['step']}", flush=True)
    n_params = sum(p.numel() for p in model.parameters())

    def save(path, full):
        ck = {"model": {k: v.detach().cpu().half() if v.is_floating_point() else v.cpu()
                        for k, v in model.state_dict().items()} if not full else model.state_dict(),
              "config": json.dumps(config), "state": state}
        if full:
            ck.update(opt=opt.state_dict(), sched=sched.state_dict(), gen=gen.get_state(),
                      rng=rng.bit_generator.state)
        torch.save(ck, path + ".tmp")
        os.replace(path + ".tmp", path)

    def write_curve():
        with open(os.path.join(a.out, "curve.csv"), "w", newline="") as fh:
            wr = csv.writer(fh)
            wr.writerow(["step", "seconds", "train_loss", "val_mae_px", "heuristic_mae_px"])
            wr.writerows([[r["step"], round(r["seconds"], 1), r["train_loss"], r["val_mae_px"], r["heuristic_mae_px"]]
                          for r in state["curve"]])
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(5, 3.2))
            s = [r["step"] for r in state["curve"]]
            ax.plot(s, [r["val_mae_px"] for r in state["curve"]], label="learned (val)")
            ax.plot(s, [r["heuristic_mae_px"] for r in state["curve"]], "--", label="contact line (val)")
            ax.set_xlabel("step"); ax.set_ylabel("pixel-height MAE [px]"); ax.legend(); fig.tight_layout()
            fig.savefig(os.path.join(a.out, "curve.png"), dpi=90); plt.close(fig)
        except Exception as e:  # noqa: BLE001 -- the plot is a convenience
            print("curve plot failed:", e)

    t0 = time.perf_counter()
    t_ck = t0
    sec0 = state["seconds"]
    losses = []
    model.train()
    N = len(train["x"])
    # the crops live on the training device once (float16: 0.8 GB for 12 k crops of 64^2), so a
    # step gathers its batch there instead of indexing and copying on the host each step; the
    # batches are the same (the same rng draws the same indices)
    on_dev = {k: torch.from_numpy(np.ascontiguousarray(train[k])).to(device) for k in ("x", "t", "w")}
    while state["step"] < a.steps:
        idx = torch.from_numpy(rng.integers(N, size=a.batch)).to(device)
        x, t, w = (on_dev[k].index_select(0, idx).float() for k in ("x", "t", "w"))
        x, t, w = augment(x, t, w, gen, a.stretch)
        p, e = split_output(model(x))
        if a.pin:
            p = contact_pin(p, x)
        loss = masked_loss(p, t, w)
        if e is not None:
            loss = loss + 0.1 * error_head_loss(e, p, x, t, w)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step(); sched.step()
        losses.append(loss.detach())        # no host sync per step; read at validation
        state["step"] += 1
        state["seconds"] = sec0 + time.perf_counter() - t0
        step = state["step"]
        if step % a.val_every == 0 or step == a.steps:
            mae, hmae = evaluate(model, val, device)
            state["curve"].append({"step": step, "seconds": state["seconds"],
                                   "train_loss": float(torch.stack(losses).mean()),
                                   "val_mae_px": mae, "heuristic_mae_px": hmae})
            losses = []
            print(f"step {step}: train loss {state['curve'][-1]['train_loss']:.4f}, val MAE {mae:.2f} px "
                  f"(heuristic {hmae:.2f} px), {state['seconds']:.0f} s", flush=True)
            if mae < state["best"]:
                state["best"] = mae
                save(os.path.join(a.out, "best.pt"), full=False)
            write_curve()
            save(last, full=True); t_ck = time.perf_counter()
        elif time.perf_counter() - t_ck > 60 * a.checkpoint_minutes:
            save(last, full=True); t_ck = time.perf_counter()
        if time.perf_counter() - t0 > 60 * a.minutes:
            print("time limit reached", flush=True)
            break
    save(last, full=True)
    info = {"command": " ".join(["python -m pixgraph_lab.height.train"] + (argv or sys.argv[1:])),
            "seed": a.seed, "config": config, "params": n_params, "steps": state["step"],
            "batch": a.batch, "train_samples": N, "val_samples": len(val["x"]),
            "seconds": round(state["seconds"], 1), "best_val_mae_px": state["best"],
            "device": str(device), "threads": a.threads, "curve": state["curve"]}
    with open(os.path.join(a.out, "train.json"), "w") as fh:
        json.dump(info, fh, indent=1)
    print(f"done: step {state['step']}, best val MAE {state['best']:.2f} px", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
