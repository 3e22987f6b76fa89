"""Compositing in linear light: apply a shadow to a background, then the cutout over it."""
from __future__ import annotations

import numpy as np


def _hwc(a: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float32)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3:
        raise ValueError(f"{name} must be (H, W) or (H, W, C), got shape {a.shape}")
    return a


def apply_shadow(background: np.ndarray, darkness: np.ndarray, opacity: float = 1.0,
                 tint=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Darken a linear-light background by a shadow, float32 like ``background``.

    ``shadowed = bg * (1 - opacity * darkness * (1 - tint))`` per colour channel:
    darkness (H, W) in [0, 1] (1 = full shadow), opacity in [0, 1] the shadow's
    strength, tint (r, g, b) in [0, 1] the fraction of each channel that survives
    full shadow (the ambient/sky fill colour; 0 = black shadow). Working in linear
    light keeps a 50 % shadow at half the light. An alpha channel (C = 2 or 4) is
    left alone: a shadow changes colour, not coverage.
    """
    bg = _hwc(background, "background")
    d = np.clip(np.asarray(darkness, dtype=np.float32), 0.0, 1.0)
    if d.shape != bg.shape[:2]:
        raise ValueError(f"shadow is {d.shape[::-1]} but the background is {bg.shape[1::-1]} (W, H)")
    ncol = 3 if bg.shape[2] >= 3 else 1
    tint = np.asarray(tint, dtype=np.float32).reshape(-1)
    if tint.size == 1:
        tint = np.repeat(tint, ncol)
    t = tint[:ncol] if ncol == 3 else tint[:1]
    factor = 1.0 - float(opacity) * d[:, :, None] * (1.0 - t[None, None, :])
    out = bg.copy()
    out[:, :, :ncol] = bg[:, :, :ncol] * factor
    return out.reshape(np.shape(background)) if np.ndim(background) == 2 else out


def over(fg_premultiplied: np.ndarray, alpha: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Premultiplied *over*: ``out = fg + bg * (1 - alpha)`` per channel, float32.

    fg_premultiplied: (H, W, C') colour already multiplied by alpha; its own alpha
    channel, if any, is ignored in favour of ``alpha`` (H, W). The result has the
    background's channel count; when the background has alpha (C = 4) the output
    alpha is ``alpha + bg_alpha (1 - alpha)``.
    """
    bg = _hwc(background, "background")
    fg = _hwc(fg_premultiplied, "cutout")
    a = np.clip(np.asarray(alpha, dtype=np.float32), 0.0, 1.0)
    if fg.shape[:2] != bg.shape[:2] or a.shape != bg.shape[:2]:
        raise ValueError(f"cutout {fg.shape[1::-1]}, alpha {a.shape[::-1]} and background "
                         f"{bg.shape[1::-1]} must have the same size (W, H)")
    C = bg.shape[2]
    ncol = 3 if C >= 3 else 1
    fcol = fg[:, :, :3] if fg.shape[2] >= 3 else np.repeat(fg[:, :, :1], ncol, axis=2)
    if ncol == 1 and fcol.shape[2] == 3:
        fcol = fcol.mean(axis=2, keepdims=True)
    out = np.empty_like(bg)
    out[:, :, :ncol] = fcol[:, :, :ncol] + bg[:, :, :ncol] * (1.0 - a[:, :, None])
    if C > ncol:
        out[:, :, ncol] = a + bg[:, :, ncol] * (1.0 - a)
    return out


def composite(background, cutout, alpha, darkness=None, opacity: float = 1.0, tint=(0.0, 0.0, 0.0)):
    """Shadow on the background (``apply_shadow``), then the cutout over it (``over``)."""
    bg = _hwc(background, "background")
    if darkness is not None:
        bg = apply_shadow(bg, darkness, opacity, tint)
    return over(cutout, alpha, bg)
