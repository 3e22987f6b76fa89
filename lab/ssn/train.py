"""Train SSN++ (or an ablation variant) on prepared buffer-channel shards.

    python -m pixgraph_lab.ssn.train --data data/ssn_train --variant ssnpp \
        --out runs/ssnpp --minutes 90 --seed 0

Seeded and resumable: the run folder holds ``checkpoint.pt`` (model, optimiser,
step, RNG states) and ``log.csv``; running the same command again continues.
Writes ``loss.png`` (training and validation loss curves) and, at the end,
``model.pt`` + ``model.json`` (config, data seed, metrics) in the shipped format
of ``pixgraph_nodes.ops.ssn.save_model``.

Data: a folder of ``.npz`` shards written by ``pixgraph_lab.ssn.prepare``; each
holds ``x`` (N, C_all, H, W) float16 buffer channels in the order of
``channels``, ``softness`` (N,), ``target`` (N, H, W) float16 ground-truth
darkness and ``weight`` (N, H, W) uint8 (1 outside the cutout, where the loss
counts).
"""
from __future__ import annotations

import argparse
import csv
import json
import pathlib
import random
import time

import numpy as np
import torch
import torch.nn.functional as F
from tqdm import tqdm

from pixgraph_nodes.ops import ssn


def load_shards(folder: pathlib.Path, variant: str):
    """All shards of a prepared folder as tensors: x (N, C, H, W) float16 (converted
    to float32 a batch at a time: 5,000 scenes are 5.9 GB in float16), softness,
    target (float16), weight (uint8)."""
    files = sorted(folder.glob("*.npz"))
    if not files:
        raise SystemExit(f"{folder}: no prepared .npz shards (run pixgraph_lab.ssn.prepare first)")
    sizes = []
    for f in files:
        with np.load(f) as z:
            sizes.append(len(z["softness"]))
    x = t = w = None
    ss = []
    at = 0
    for f, n in zip(files, sizes):
        with np.load(f) as z:
            names = [str(c) for c in z["channels"]]
            idx = [names.index(c) for c in ssn.VARIANTS[variant]]
            xs = z["x"][:, idx]
            if x is None:   # filled shard by shard: no second copy of the whole set
                x = np.empty((sum(sizes), len(idx)) + xs.shape[2:], np.float16)
                t = np.empty((sum(sizes),) + xs.shape[2:], np.float16)
                w = np.empty((sum(sizes),) + xs.shape[2:], np.uint8)
            x[at:at + n] = xs
            t[at:at + n] = z["target"]
            w[at:at + n] = z["weight"]
            ss.append(z["softness"].astype(np.float32))
            at += n
    # pixel-unit channels were stored already normalised by prepare (stack_channels)
    return torch.from_numpy(x), torch.from_numpy(np.concatenate(ss)), torch.from_numpy(t), torch.from_numpy(w)


def split_indices(n: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(validation, training) sample indices when no ``--val`` is given: 5 % held
    out by a permutation seeded 1234 (``compare_runs`` reads the same split)."""
    perm = torch.randperm(n, generator=torch.Generator().manual_seed(1234))
    nval = max(1, n // 20)
    return perm[:nval], perm[nval:]


def augment(x, target, weight, gen: torch.Generator):
    """Horizontal flips: a mirrored scene is a valid scene. The x-gradient of the
    background pixel height changes sign under the flip."""
    flip = torch.rand(x.shape[0], generator=gen) < 0.5
    if flip.any():
        x = x.clone()
        x[flip] = x[flip].flip(-1)
        target = target.clone()
        target[flip] = target[flip].flip(-1)
        weight = weight.clone()
        weight[flip] = weight[flip].flip(-1)
    return x, target, weight, flip


def masked_loss(pred, target, weight):
    """L1 + L2 on darkness, only where the loss counts (outside the cutout)."""
    d = (pred[:, 0] - target) * weight
    n = weight.sum().clamp_min(1.0)
    return (d.abs().sum() + (d * d).sum() * 10.0) / n


def _gauss_taps(sigma: float = 1.5, radius: int = 5) -> torch.Tensor:
    """The 11-tap Gaussian of the benchmark's SSIM (``pixgraph_lab.metrics``)."""
    x = torch.arange(-radius, radius + 1, dtype=torch.float32)
    k = torch.exp(-0.5 * (x / sigma) ** 2)
    return k / k.sum()


def _blur(img, taps):
    """Separable Gaussian of (N, 1, H, W), zero padded."""
    r = len(taps) // 2
    img = F.conv2d(img, taps.view(1, 1, 1, -1), padding=(0, r))
    return F.conv2d(img, taps.view(1, 1, -1, 1), padding=(r, 0))


def ssim_map(p, g, taps, c1: float = 0.01 ** 2, c2: float = 0.03 ** 2):
    """Per-pixel SSIM of (N, 1, H, W) darkness maps (data range 1), as the benchmark's."""
    mp, mg = _blur(p, taps), _blur(g, taps)
    spp = _blur(p * p, taps) - mp * mp
    sgg = _blur(g * g, taps) - mg * mg
    spg = _blur(p * g, taps) - mp * mg
    return ((2 * mp * mg + c1) * (2 * spg + c2)) / ((mp * mp + mg * mg + c1) * (spp + sgg + c2))


def structure_loss(pred, target, weight, ssim_weight: float, grad_weight: float):
    """``masked_loss`` plus terms that reward the shadow's structure.

    * ``ssim_weight * (1 - SSIM)``: the benchmark's SSIM (11-tap Gaussian window),
      with pixels that do not count set equal to the target (as the metric does),
      averaged over the counted pixels. It punishes penumbrae of the wrong width and
      low-contrast streaks that RMSE barely sees.
    * ``grad_weight * L1`` of the darkness gradient (x and y finite differences)
      where both pixels count: a doubled or streaky shadow has edges the target
      lacks, a too-wide penumbra too-small gradients.
    """
    base = masked_loss(pred, target, weight)
    if ssim_weight <= 0 and grad_weight <= 0:
        return base
    p = pred[:, :1]
    g = target[:, None]
    w = weight[:, None]
    p = torch.where(w > 0, p, g)
    n = w.sum().clamp_min(1.0)
    out = base
    if ssim_weight > 0:
        taps = _gauss_taps().to(p.device)
        out = out + ssim_weight * ((1.0 - ssim_map(p, g, taps)) * w).sum() / n
    if grad_weight > 0:
        wx = w[..., :, 1:] * w[..., :, :-1]
        wy = w[..., 1:, :] * w[..., :-1, :]
        dx = (p[..., :, 1:] - p[..., :, :-1]) - (g[..., :, 1:] - g[..., :, :-1])
        dy = (p[..., 1:, :] - p[..., :-1, :]) - (g[..., 1:, :] - g[..., :-1, :])
        out = out + grad_weight * ((dx.abs() * wx).sum() + (dy.abs() * wy).sum()) / n
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", required=True, type=pathlib.Path, help="prepared training shards")
    ap.add_argument("--val", type=pathlib.Path, help="prepared validation shards (default: 5%% of --data)")
    ap.add_argument("--variant", default="ssnpp", choices=sorted(ssn.VARIANTS))
    ap.add_argument("--base", type=int, default=8, help="channels of the first U-Net level")
    ap.add_argument("--levels", type=int, default=4)
    ap.add_argument("--out", required=True, type=pathlib.Path)
    ap.add_argument("--minutes", type=float, default=90.0, help="wall-clock training budget")
    ap.add_argument("--max-steps", type=int, default=10**9)
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--lr", type=float, default=2e-3)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=0, help="torch threads (0: torch's default)")
    ap.add_argument("--eval-every", type=float, default=60.0,
                    help="seconds between validation runs (and checkpoints); a 5%% validation split of "
                         "5,800 scenes takes ~20 s on one core")
    ap.add_argument("--init", type=pathlib.Path,
                    help="start from these weights (a model.pt / shipped .pt of the same config) "
                         "instead of a random initialisation; recorded in the model's provenance")
    ap.add_argument("--ssim-weight", type=float, default=0.0,
                    help="weight of the (1 - SSIM) structure term (0: plain L1 + L2, the first model)")
    ap.add_argument("--grad-weight", type=float, default=0.0,
                    help="weight of the gradient-L1 structure term (0: off)")
    args = ap.parse_args(argv)

    if args.threads:
        torch.set_num_threads(args.threads)
    dev = torch.device("cuda" if torch.cuda.is_available() else "cpu")
    args.out.mkdir(parents=True, exist_ok=True)
    x, s, t, w = load_shards(args.data, args.variant)
    if args.val:
        vx, vs, vt, vw = load_shards(args.val, args.variant)
        train_idx = torch.arange(len(x))
    else:
        vi, ti = split_indices(len(x))
        vx, vs, vt, vw = x[vi], s[vi], t[vi], w[vi]
        # the training samples are drawn through ``train_idx``: x[ti] would copy
        # the whole set (another 6-7 GB for 5,800 scenes)
        train_idx = ti

    config = ssn.SSNConfig(variant=args.variant, base=args.base, levels=args.levels)
    torch.manual_seed(args.seed)
    random.seed(args.seed)
    model = ssn.SSN(config).to(dev)
    init_info = None
    if args.init:
        blob = torch.load(args.init, map_location="cpu", weights_only=True)
        if blob["config"] != vars(config):
            raise SystemExit(f"{args.init}: weights for {blob['config']}, not {vars(config)}")
        model.load_state_dict({k: v.float() for k, v in blob["state"].items()})
        import hashlib
        init_info = {"path": str(args.init), "sha256": hashlib.sha256(args.init.read_bytes()).hexdigest()[:16],
                     "its_meta": {k: blob["meta"].get(k) for k in ("train_data", "steps", "seed", "val_rmse")}}
    opt = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=1e-4)
    step, elapsed = 0, 0.0
    gen = torch.Generator().manual_seed(args.seed)
    ckpt = args.out / "checkpoint.pt"
    if ckpt.exists():
        blob = torch.load(ckpt, map_location=dev, weights_only=False)
        if blob["config"] != vars(config):
            raise SystemExit(f"{ckpt}: written for {blob['config']}, not {vars(config)}; use another --out")
        model.load_state_dict(blob["model"])
        opt.load_state_dict(blob["opt"])
        step, elapsed = blob["step"], blob["elapsed"]
        gen.set_state(blob["gen"])
        torch.set_rng_state(blob["torch_rng"])
        print(f"resumed at step {step} ({elapsed / 60:.1f} min)")
    log_path = args.out / "log.csv"
    new_log = not log_path.exists() or step == 0
    log = open(log_path, "w" if new_log else "a", newline="")
    writer = csv.writer(log)
    if new_log:
        writer.writerow(["step", "minutes", "train_loss", "val_loss", "val_rmse"])

    budget = args.minutes * 60.0
    bar = tqdm(total=int(budget), initial=int(elapsed), unit="s", desc=f"train {args.variant}")
    t0 = time.perf_counter() - elapsed
    running, seen = 0.0, 0
    last_eval = elapsed
    while step < args.max_steps:
        elapsed = time.perf_counter() - t0
        if elapsed >= budget:
            break
        # cosine decay over the wall-clock budget: steps per second are not known ahead
        lr = args.lr * 0.5 * (1 + np.cos(np.pi * min(1.0, elapsed / budget)))
        for gr in opt.param_groups:
            gr["lr"] = lr
        model.train()
        idx = train_idx[torch.randint(0, len(train_idx), (args.batch,), generator=gen)]
        xb, tb, wb, flip = augment(x[idx].float(), t[idx].float(), w[idx].float(), gen)
        if "bg_gradient_x" in config.channels and flip.any():
            ci = config.channels.index("bg_gradient_x")
            xb[flip, ci] = -xb[flip, ci]
        pred = model(xb.to(dev), s[idx].to(dev))
        loss = structure_loss(pred, tb.to(dev), wb.to(dev), args.ssim_weight, args.grad_weight)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        step += 1
        running += loss.item()
        seen += 1
        bar.update(int(time.perf_counter() - t0) - bar.n)
        if elapsed - last_eval >= args.eval_every or step == 1:
            last_eval = elapsed
            vl, vr = evaluate(model, vx, vs, vt, vw, dev)
            writer.writerow([step, round(elapsed / 60, 2), round(running / max(seen, 1), 5), round(vl, 5), round(vr, 5)])
            log.flush()
            bar.set_postfix(step=step, train=f"{running / max(seen, 1):.4f}", val_rmse=f"{vr:.4f}")
            running, seen = 0.0, 0
            torch.save({"config": vars(config), "model": model.state_dict(), "opt": opt.state_dict(),
                        "step": step, "elapsed": elapsed, "gen": gen.get_state(),
                        "torch_rng": torch.get_rng_state()}, ckpt)
    bar.close()
    log.close()
    vl, vr = evaluate(model, vx, vs, vt, vw, dev)
    plot_log(log_path, args.out / "loss.png")
    meta = {"train_data": str(args.data), "seed": args.seed, "steps": step,
            "loss": {"l1": 1.0, "l2": 10.0, "ssim": args.ssim_weight, "grad": args.grad_weight},
            "init": init_info, "lr": args.lr, "batch": args.batch,
            "minutes": round((time.perf_counter() - t0) / 60, 1), "val_rmse": round(vr, 5),
            "params": ssn.count_params(model), "gflops_256": round(ssn.count_flops(model.cpu()) / 1e9, 3),
            "data_info": _data_info(args.data)}
    ssn.save_model(model.cpu(), args.out / "model.pt", meta)
    print(json.dumps(meta, indent=1))
    return 0


def _data_info(folder: pathlib.Path) -> dict:
    info = folder / "info.json"
    return json.loads(info.read_text()) if info.exists() else {}


@torch.no_grad()
def evaluate(model, x, s, t, w, dev, batch: int = 16) -> tuple[float, float]:
    """(masked loss, RMSE over the counted pixels) on a held-out set."""
    model.eval()
    tot_loss, se, n = 0.0, 0.0, 0.0
    for i in range(0, len(x), batch):
        pred = model(x[i:i + batch].float().to(dev), s[i:i + batch].to(dev))
        tb, wb = t[i:i + batch].float().to(dev), w[i:i + batch].float().to(dev)
        tot_loss += masked_loss(pred, tb, wb).item() * len(tb)
        d = (pred[:, 0] - tb) * wb
        se += (d * d).sum().item()
        n += wb.sum().item()
    return tot_loss / len(x), float(np.sqrt(se / max(n, 1.0)))


def plot_log(log_path: pathlib.Path, png: pathlib.Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = list(csv.DictReader(open(log_path)))
    if not rows:
        return
    m = [float(r["minutes"]) for r in rows]
    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(m, [float(r["train_loss"]) for r in rows], label="train loss")
    ax.plot(m, [float(r["val_loss"]) for r in rows], label="validation loss")
    ax.plot(m, [float(r["val_rmse"]) for r in rows], label="validation RMSE")
    ax.set_xlabel("minutes")
    ax.set_yscale("log")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(png, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
