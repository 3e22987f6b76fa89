"""Weight averages of cutout-height networks fine-tuned from one start (docs/height-record.md,
"Rules fixed before measuring: weight averages of the seventh").

    # S2: the uniform average of two runs; W50: 7c pulled half way back to the start
    python -m pixgraph_lab.height.soup --members runs/h7b/best.pt runs/h7c/best.pt \\
        --bn-data data/hsnap --out runs/soup_s2.pt
    python -m pixgraph_lab.height.soup --members runs/h7c/best.pt --pull 0.5 \\
        --start-widen-from runs/height_v5.pt --bn-data data/hsnap --out runs/soup_w50.pt

A "model soup" averages, tensor by tensor, the weights of several networks trained
from the same starting weights; ``--pull a`` then takes ``(1 - a) * start + a * soup``,
the start being rebuilt exactly as the training script built it (``widen.widen_state``
of ``--start-widen-from`` with ``--widen-noise`` and ``--seed``). BatchNorm's running
mean and variance are not weights that average: they are re-estimated afterwards
(``recalibrate_bn``) from ``--bn-crops`` augmented training crops of ``--bn-data``
(the training script's ``load_splits`` and ``augment``, seeded). The result is a
checkpoint like the training script's ``best.pt``, with the inference settings
(``config["inference"]``: pin, foot snap, auto's rule) of ``--inference-from``
(default: the last member) and the recipe under ``config["soup"]``.
"""
from __future__ import annotations

import argparse
import json
import os

import numpy as np

#: BatchNorm buffers: re-estimated, never averaged
_BN_STATS = ("running_mean", "running_var", "num_batches_tracked")


def average_states(states: list, weights=None) -> dict:
    """The weighted mean (default uniform) of state dicts with equal keys and shapes,
    in float32; integer tensors (BatchNorm's batch counts) taken from the first."""
    import torch
    if not states:
        raise ValueError("nothing to average")
    keys = list(states[0])
    for i, st in enumerate(states[1:], 1):
        if list(st) != keys or any(st[k].shape != states[0][k].shape for k in keys):
            raise ValueError(f"member {i} has other tensors than member 0: not the same network")
    w = np.full(len(states), 1.0 / len(states)) if weights is None else np.asarray(weights, np.float64)
    if w.shape != (len(states),) or not np.isclose(w.sum(), 1.0):
        raise ValueError(f"weights must be one per member and sum to 1, got {list(w)}")
    out = {}
    for k in keys:
        if states[0][k].is_floating_point():
            out[k] = sum(float(wi) * st[k].float() for wi, st in zip(w, states))
        else:
            out[k] = states[0][k].clone()
    return out


def pull_toward(start: dict, state: dict, a: float) -> dict:
    """``(1 - a) * start + a * state`` for every floating tensor (a = 1: ``state``)."""
    if set(start) != set(state):
        raise ValueError("the start and the state are not the same network")
    return {k: (1.0 - a) * start[k].float() + a * v.float() if v.is_floating_point() else v.clone()
            for k, v in state.items()}


def recalibrate_bn(model, x: np.ndarray, t: np.ndarray, w: np.ndarray, crops: int, batch: int = 64,
                   seed: int = 0) -> int:
    """Re-estimate every BatchNorm's running mean and variance as the average of the
    per-batch statistics over ``crops`` augmented crops drawn (seeded) from the training
    arrays ``x, t, w`` (``train.load_splits``'s), ``batch`` at a time (the mean over all
    crops when ``crops`` is a multiple of ``batch``, as the default 2,048 / 64 is); the
    weights are not touched. Returns the crops used."""
    import torch

    from .train import augment
    bns = [m for m in model.modules() if isinstance(m, torch.nn.modules.batchnorm._BatchNorm)]
    for m in bns:
        m.reset_running_stats()
        m.momentum = None                          # cumulative average over the batches
    rng = np.random.default_rng(seed)
    gen = torch.Generator().manual_seed(seed)
    idx = rng.choice(len(x), size=min(crops, len(x)), replace=False)
    model.train()
    with torch.no_grad():
        for i in range(0, len(idx), batch):
            j = idx[i:i + batch]
            xb, _, _ = augment(torch.from_numpy(x[j].astype(np.float32)), torch.from_numpy(t[j].astype(np.float32)),
                               torch.from_numpy(w[j].astype(np.float32)), gen)
            model(xb)
    for m in bns:
        m.momentum = 0.1
    model.eval()
    return len(idx)


def _load(path: str):
    import torch
    ck = torch.load(path, map_location="cpu", weights_only=True)
    return ck["model"], json.loads(ck["config"]) if isinstance(ck["config"], str) else dict(ck["config"])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pixgraph_lab.height.soup", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--members", nargs="+", required=True, help="best.pt of runs from one start")
    ap.add_argument("--pull", type=float, default=1.0, help="a in (1 - a) start + a soup; 1 = the soup itself")
    ap.add_argument("--start-widen-from", default=None,
                    help="with --pull < 1: the narrower checkpoint the runs were widened from")
    ap.add_argument("--widen-noise", type=float, default=0.01)
    ap.add_argument("--seed", type=int, default=5, help="the runs' --seed (it seeded the widening)")
    ap.add_argument("--inference-from", default=None, help="checkpoint whose config['inference'] to keep")
    ap.add_argument("--bn-data", required=True, help="snapshot folder with the training crop caches")
    ap.add_argument("--bn-splits", default="train,train_organic")
    ap.add_argument("--bn-crops", type=int, default=2048)
    ap.add_argument("--bn-seed", type=int, default=0)
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    import torch
    torch.set_num_threads(1)
    from pixgraph_nodes.ops.learned_height import build_model

    from .train import load_splits
    states, configs = zip(*(_load(p) for p in a.members))
    cfg = dict(configs[-1])
    for p, c in zip(a.members, configs):
        if (c["base"], c["levels"], c.get("outputs", 1), c["size"]) != (cfg["base"], cfg["levels"],
                                                                          cfg.get("outputs", 1), cfg["size"]):
            raise SystemExit(f"{p}: another architecture than {a.members[-1]}")
    state = average_states(list(states))
    if a.pull != 1.0:
        if not a.start_widen_from:
            raise SystemExit("--pull < 1 needs --start-widen-from (the start the runs were widened from)")
        from .widen import widen_state
        st0, c0 = _load(a.start_widen_from)
        start = widen_state(st0, int(c0["base"]), int(cfg["base"]), int(cfg["levels"]), a.widen_noise, a.seed)
        state = pull_toward(start, state, a.pull)
    model = build_model(int(cfg["base"]), int(cfg["levels"]), int(cfg.get("outputs", 1)))
    model.load_state_dict(state)
    train = load_splits(a.bn_data, a.bn_splits.split(","), int(cfg["size"]))
    used = recalibrate_bn(model, train["x"], train["t"], train["w"], a.bn_crops, seed=a.bn_seed)
    if a.inference_from:
        cfg["inference"] = _load(a.inference_from)[1].get("inference")
    cfg["soup"] = {"members": list(a.members), "pull": a.pull, "start_widen_from": a.start_widen_from,
                   "widen_noise": a.widen_noise, "seed": a.seed, "bn_crops": used, "bn_splits": a.bn_splits,
                   "bn_seed": a.bn_seed}
    ck = {"model": {k: v.detach().half() if v.is_floating_point() else v for k, v in model.state_dict().items()},
          "config": json.dumps(cfg), "state": {"soup": True}}
    torch.save(ck, a.out + ".tmp")
    os.replace(a.out + ".tmp", a.out)
    print(f"{a.out}: {len(a.members)} member(s), pull {a.pull}, BatchNorm re-estimated on {used} crops")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
