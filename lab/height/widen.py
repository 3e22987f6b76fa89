"""Widen a trained cutout-height U-Net (``learned_height.build_model``) to more
channels per level without changing what it computes ("net2wider", Chen et al.
2016): the starting point for a wider candidate, so its training begins where the
narrower model ended instead of from scratch.

Every convolution of width ``c`` becomes ``c'`` wide: its first ``c`` output
channels are the old ones and each extra channel copies a randomly chosen old
one (weights and BatchNorm statistics alike). ReLU, max pooling, bilinear
upsampling and BatchNorm act per channel, so a copy stays a copy through them.
The next convolution reads each old input channel ``s`` now ``n_s`` times, so
its weights for those inputs are divided by ``n_s``: the sum over the copies is
the old weight times the old channel. The U-Net's concatenations (upsampled
deeper features, then the skip) concatenate the two channel mappings. The input
(6 channels) and the head's outputs keep their widths. ``noise`` (a fraction of
each weight tensor's standard deviation) breaks the copies' symmetry so they can
learn different things; with ``noise=0`` the wider network gives the narrower
one's outputs up to float rounding (``tests/test_height_widen.py``).
"""
from __future__ import annotations

import numpy as np


def _mapping(old: int, new: int, rng) -> np.ndarray:
    """Which old channel each of ``new`` channels copies: the old ones first, then random copies."""
    if new < old:
        raise ValueError(f"cannot narrow {old} channels to {new}")
    return np.concatenate([np.arange(old), rng.integers(0, old, new - old)]).astype(np.int64)


def widen_state(state: dict, base: int, new_base: int, levels: int, noise: float = 0.0, seed: int = 0) -> dict:
    """A state dict of ``build_model(base, levels)`` -> one of ``build_model(new_base, levels)``
    computing the same function (module doc); tensors are torch tensors, float32 out."""
    import torch
    rng = np.random.default_rng(seed)
    old_ch = [base * 2 ** k for k in range(levels + 1)]
    new_ch = [new_base * 2 ** k for k in range(levels + 1)]
    sd = {k: v.float().clone() if v.is_floating_point() else v.clone() for k, v in state.items()}
    out = dict(sd)

    def conv(name_conv, name_bn, g_in, g_out):
        w = sd[f"{name_conv}.weight"]                      # (out, in, kh, kw)
        cnt = np.bincount(g_in, minlength=w.shape[1]).astype(np.float32)
        w2 = w[torch.from_numpy(g_out)][:, torch.from_numpy(g_in)] / torch.from_numpy(cnt[g_in])[None, :, None, None]
        if noise:
            w2 = w2 + noise * float(w.std()) * torch.from_numpy(rng.standard_normal(tuple(w2.shape)).astype(np.float32))
        out[f"{name_conv}.weight"] = w2
        if f"{name_conv}.bias" in sd:
            out[f"{name_conv}.bias"] = sd[f"{name_conv}.bias"][torch.from_numpy(g_out)]
        if name_bn:
            for p in ("weight", "bias", "running_mean", "running_var"):
                out[f"{name_bn}.{p}"] = sd[f"{name_bn}.{p}"][torch.from_numpy(g_out)]
        return g_out

    g = np.arange(sd["down.0.0.weight"].shape[1])          # the 6 input channels, kept
    skips = []
    for k in range(levels + 1):
        ga = conv(f"down.{k}.0", f"down.{k}.1", g, _mapping(old_ch[k], new_ch[k], rng))
        g = conv(f"down.{k}.3", f"down.{k}.4", ga, _mapping(old_ch[k], new_ch[k], rng))
        skips.append(g)
    g = skips.pop()
    for k in reversed(range(levels)):
        skip = skips.pop()
        cat = np.concatenate([g, skip + old_ch[k + 1]])     # [upsampled deeper, skip] as in forward
        ga = conv(f"up.{k}.0", f"up.{k}.1", cat, _mapping(old_ch[k], new_ch[k], rng))
        g = conv(f"up.{k}.3", f"up.{k}.4", ga, _mapping(old_ch[k], new_ch[k], rng))
    outputs = sd["head.weight"].shape[0]
    conv("head", None, g, np.arange(outputs))
    return out
