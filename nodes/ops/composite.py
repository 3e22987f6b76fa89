"""Compositing in linear light: apply a shadow to a background, then the cutout over it."""
from __future__ import annotations

import numpy as np

from .memo import FrozenMemo
from .resample import nonzero_box

#: the box a frozen cutout touches (ops/memo.py): a light sweep composites the same cutout again and again
_BOXES = FrozenMemo(size=4)


def _hwc(a: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float32)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3:
        raise ValueError(f"{name} must be (H, W) or (H, W, C), got shape {a.shape}")
    return a


def _shadow_into(out: np.ndarray, darkness: np.ndarray, opacity: float, tint) -> None:
    """``apply_shadow`` in place on ``out`` (H, W, C) float32, only over the box
    where the darkness is above 0 (elsewhere the factor is exactly 1)."""
    d = np.asarray(darkness, dtype=np.float32)
    if d.shape != out.shape[:2]:
        raise ValueError(f"shadow is {d.shape[::-1]} but the background is {out.shape[1::-1]} (W, H)")
    box = nonzero_box(d > 0.0)
    if box is None or opacity == 0.0:
        return
    r0, r1, c0, c1 = box
    ncol = 3 if out.shape[2] >= 3 else 1
    tint = np.asarray(tint, dtype=np.float32).reshape(-1)
    if tint.size == 1:
        tint = np.repeat(tint, ncol)
    t = tint[:ncol] if ncol == 3 else tint[:1]
    sub = np.clip(d[r0:r1, c0:c1], np.float32(0.0), np.float32(1.0))
    factor = np.empty_like(sub)
    for c in range(ncol):
        # bg * (1 - opacity * d * (1 - tint_c)), one channel at a time: no (H, W, 3) temporaries
        np.multiply(sub, np.float32(-float(opacity) * (1.0 - float(t[c]))), out=factor)
        factor += np.float32(1.0)
        out[r0:r1, c0:c1, c] *= factor


def apply_shadow(background: np.ndarray, darkness: np.ndarray, opacity: float = 1.0,
                 tint=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Darken a linear-light background by a shadow, float32 like ``background``.

    ``shadowed = bg * (1 - opacity * darkness * (1 - tint))`` per colour channel:
    darkness (H, W) in [0, 1] (1 = full shadow; clipped), opacity in [0, 1] the
    shadow's strength, tint (r, g, b) in [0, 1] the fraction of each channel that
    survives full shadow (the ambient/sky fill colour; 0 = black shadow). Working
    in linear light keeps a 50 % shadow at half the light. An alpha channel
    (C = 2 or 4) is left alone: a shadow changes colour, not coverage. Only the
    box where the darkness is above 0 is computed (a 20 MP photo's shadow covers
    a part of it).
    """
    bg = _hwc(background, "background")
    out = bg.copy()
    _shadow_into(out, darkness, opacity, tint)
    return out.reshape(np.shape(background)) if np.ndim(background) == 2 else out


def _over_into(out: np.ndarray, fg_premultiplied: np.ndarray, alpha: np.ndarray) -> None:
    """``over`` in place on ``out`` (the background, (H, W, C) float32), only over the
    box where the cutout has coverage or colour (elsewhere the result is ``out``)."""
    fg = _hwc(fg_premultiplied, "cutout")
    a = np.asarray(alpha, dtype=np.float32)
    if fg.shape[:2] != out.shape[:2] or a.shape != out.shape[:2]:
        raise ValueError(f"cutout {fg.shape[1::-1]}, alpha {a.shape[::-1]} and background "
                         f"{out.shape[1::-1]} must have the same size (W, H)")
    C = out.shape[2]
    ncol = 3 if C >= 3 else 1
    nf = min(fg.shape[2], 3)
    key = (fg_premultiplied, alpha)
    box = _BOXES.get(key)
    if box is None:
        touched = a != 0.0
        for c in range(nf):
            touched |= fg[:, :, c] != 0.0
        box = nonzero_box(touched) or ()
        _BOXES.put(key, None, box)
    if not box:
        return
    r0, r1, c0, c1 = box
    ab = np.clip(a[r0:r1, c0:c1], 0.0, 1.0)
    keep = np.float32(1.0) - ab
    fb = fg[r0:r1, c0:c1]
    if ncol == 3 and nf == 3:
        cols = [fb[:, :, c] for c in range(3)]
    elif ncol == 3:
        cols = [fb[:, :, 0]] * 3
    else:
        cols = [fb[:, :, :3].mean(axis=2) if nf == 3 else fb[:, :, 0]]
    for c in range(ncol):
        ob = out[r0:r1, c0:c1, c]
        ob *= keep
        ob += cols[c]
    if C > ncol:
        ob = out[r0:r1, c0:c1, ncol]
        ob *= keep
        ob += ab


def over(fg_premultiplied: np.ndarray, alpha: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Premultiplied *over*: ``out = fg + bg * (1 - alpha)`` per channel, float32.

    fg_premultiplied: (H, W, C') colour already multiplied by alpha; its own alpha
    channel, if any, is ignored in favour of ``alpha`` (H, W). The result has the
    background's channel count; when the background has alpha (C = 4) the output
    alpha is ``alpha + bg_alpha (1 - alpha)``. Only the box the cutout touches is
    computed.
    """
    out = _hwc(background, "background").copy()
    _over_into(out, fg_premultiplied, alpha)
    return out


def composite(background, cutout, alpha, darkness=None, opacity: float = 1.0, tint=(0.0, 0.0, 0.0)):
    """Shadow on the background (``apply_shadow``), then the cutout over it (``over``),
    in one copy of the background."""
    out = _hwc(background, "background").copy()
    if darkness is not None:
        _shadow_into(out, darkness, opacity, tint)
    _over_into(out, cutout, alpha)
    return out
