"""Placing a cutout on the background's canvas: position, scale, flip, crop.

A cutout (premultiplied colour, alpha, optional pixel height, in its own pixels)
is mapped onto a canvas of the background's size by a similarity transform that
puts the cutout's *anchor* (its foot: ``lights.foot_of_mask``, the centre of the
columns reaching its lowest row, at that row's bottom edge) on the canvas point
``foot`` and scales it by ``s``:

    canvas (X, Y) = foot + s * (±(x - ax), y - ay)        (- when flipped)

Resampling is separable with a triangle filter whose support is ``max(1, 1/s)``
source pixels (bilinear when enlarging, area-like when shrinking, so small
placements do not alias). Colour is resampled premultiplied (filtering straight
colour would bleed the transparent pixels' colour into the edge); outside the
cutout the source is transparent, so the border crop needs no special case.

Pixel heights are lengths in pixels: resampled weighted by alpha (an edge pixel
keeps the object's height instead of averaging with the ground's 0), taken from
the nearest source pixel next to jumps in height (a blend across a depth edge is
a surface that does not exist), and multiplied by ``s`` (design.md §2). The foot of a placed point then lands where
the placed ground contact is: ``Y + s h = foot_v + s (y + h - ay)``.
"""
from __future__ import annotations

import math

import numpy as np

from .lights import foot_of_mask


def _weights(n_src: int, x_src: np.ndarray, support: float) -> np.ndarray:
    """Dense (len(x_src), n_src) resampling weights: row j samples the source at the
    continuous coordinate ``x_src[j]`` (pixel centres at +0.5) with a triangle of
    half-width ``support`` source pixels. Rows are normalised over the source
    extended with transparent padding, so a row that reaches past the border
    fades out instead of stretching the edge pixel."""
    pad = int(math.ceil(support)) + 1
    centres = np.arange(-pad, n_src + pad, dtype=np.float64) + 0.5
    w = np.maximum(0.0, 1.0 - np.abs(centres[None, :] - x_src[:, None]) / support)
    total = w.sum(axis=1, keepdims=True)
    w = np.divide(w, total, out=np.zeros_like(w), where=total > 0)
    return w[:, pad:pad + n_src]


def _resample(planes: np.ndarray, wy: np.ndarray, wx: np.ndarray) -> np.ndarray:
    """(h, w, C) -> (len(wy), len(wx), C) with separable weights; only the canvas rows
    and columns the cutout reaches are multiplied."""
    out = np.zeros((wy.shape[0], wx.shape[0], planes.shape[2]), np.float32)
    rows = np.nonzero(wy.any(axis=1))[0]
    cols = np.nonzero(wx.any(axis=1))[0]
    if len(rows) == 0 or len(cols) == 0:
        return out
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    a, b = wy[r0:r1], wx[c0:c1]
    for c in range(planes.shape[2]):
        out[r0:r1, c0:c1, c] = a @ planes[:, :, c].astype(np.float64) @ b.T
    return out


def _jumps(h: np.ndarray, inside: np.ndarray, jump: float) -> np.ndarray:
    """(h, w) float 1 where a pixel's 3x3 neighbourhood inside the object holds a
    depth discontinuity, else 0.

    A discontinuity is a second difference of the height (along x or y, over three
    pixels inside the object) above ``jump`` px: a plane's pixel height is locally
    linear in the image however steep it is (a face seen at a grazing angle changes
    height by many px per px and is still one surface), while a step from one
    surface to another bends it by the step's size.
    """
    H, W = h.shape
    d2 = np.zeros((H, W), np.float32)
    for axis in (0, 1):
        n = h.shape[axis]
        if n < 3:
            continue
        a = [np.take(h, np.arange(k, n - 2 + k), axis=axis) for k in range(3)]
        ok = np.take(inside, np.arange(0, n - 2), axis=axis) & np.take(inside, np.arange(1, n - 1), axis=axis) \
            & np.take(inside, np.arange(2, n), axis=axis)
        c = np.where(ok, np.abs(a[0] - 2 * a[1] + a[2]), 0.0)
        if axis == 0:
            d2[1:-1, :] = np.maximum(d2[1:-1, :], c)
        else:
            d2[:, 1:-1] = np.maximum(d2[:, 1:-1], c)
    return (inside & (_filter3(d2, np.max, 0.0) > jump)).astype(np.float32)


def _filter3(a: np.ndarray, reduce, pad: float) -> np.ndarray:
    """``reduce`` (np.max / np.min) over each pixel's 3x3 neighbourhood."""
    p = np.pad(a, 1, constant_values=pad)
    H, W = a.shape
    return reduce(np.stack([p[dy:dy + H, dx:dx + W] for dy in range(3) for dx in range(3)]), axis=0)


def resize_map(height: np.ndarray, shape: tuple[int, int], rel_tol: float = 0.02) -> np.ndarray:
    """A pixel-height map for an image of ``shape`` (H, W) instead of its own size:
    resampled (weighted by h > 0, so the object's edge keeps its height) and
    multiplied by the vertical scale ``H / h`` (a pixel height is a vertical length). The two sizes must have the same aspect ratio within
    ``rel_tol``, else ``ValueError`` (a map of another picture, not a resized one)."""
    h = np.asarray(height, dtype=np.float32)
    (H, W), (hh, hw) = shape, h.shape
    if (H, W) == (hh, hw):
        return h
    sy, sx = H / hh, W / hw
    if abs(sy / sx - 1.0) > rel_tol:
        raise ValueError(f"pixel height {hw}x{hh} and cutout {W}x{H} (width x height) have different aspect "
                         f"ratios: the map is not of this cutout")
    wy = _weights(hh, (np.arange(H) + 0.5) / sy, max(1.0, 1.0 / sy))
    wx = _weights(hw, (np.arange(W) + 0.5) / sx, max(1.0, 1.0 / sx))
    # weighted by "is object" (h > 0): the top row keeps its height instead of
    # averaging with the zeros around the object
    obj = (h > 0).astype(np.float32)
    r = _resample(np.stack([h * obj, obj], axis=2), wy, wx)
    out = np.where(r[:, :, 1] > 1e-6, r[:, :, 0] / np.maximum(r[:, :, 1], 1e-6), 0.0)
    return (out * sy).astype(np.float32)


def place_cutout(image: np.ndarray, alpha: np.ndarray, height: np.ndarray | None,
                 canvas: tuple[int, int], foot, scale: float = 1.0, flip: bool = False,
                 anchor=None, jump: float = 4.0):
    """Put a cutout on a canvas of ``canvas`` = (H, W) pixels.

    image: (h, w, C) premultiplied colour; alpha: (h, w) coverage; height: (h, w)
    pixel height [cutout px] or None. foot: (u, v) canvas point [px] where the
    cutout's anchor lands; scale: size factor s > 0; flip: mirror left-right about
    the anchor. anchor: (x, y) in cutout pixels, default the alpha's foot.
    jump: a bend of the height field [cutout px] (second difference over three
    pixels) above which it is a depth edge: heights within a pixel of it are not
    blended but taken from the nearest pixel.
    Returns ``(image, alpha, height)`` on the canvas: premultiplied colour
    (H, W, C), alpha (H, W) and pixel height [canvas px] (H, W), 0 outside the
    cutout (None when ``height`` is None). Parts outside the canvas are cropped.
    """
    image = np.asarray(image, dtype=np.float32)
    alpha = np.asarray(alpha, dtype=np.float32)
    if image.ndim == 2:
        image = image[:, :, None]
    if not (scale > 0 and math.isfinite(scale)):
        raise ValueError(f"scale must be positive, got {scale}")
    h, w = alpha.shape
    ax, ay = foot_of_mask(alpha) if anchor is None else anchor
    H, W = canvas
    sign = -1.0 if flip else 1.0
    support = max(1.0, 1.0 / scale)
    xs = ax + sign * ((np.arange(W) + 0.5) - foot[0]) / scale
    ys = ay + ((np.arange(H) + 0.5) - foot[1]) / scale
    wy, wx = _weights(h, ys, support), _weights(w, xs, support)
    planes = [image, alpha[:, :, None]]
    if height is not None:
        planes.append((np.asarray(height, dtype=np.float32) * alpha)[:, :, None])
    out = _resample(np.concatenate(planes, axis=2), wy, wx)
    C = image.shape[2]
    img, a = out[:, :, :C], np.clip(out[:, :, C], 0.0, 1.0)
    placed_h = None
    if height is not None:
        hs = np.asarray(height, dtype=np.float32)
        smooth = out[:, :, C + 1] / np.maximum(a, 1e-6)
        # across a jump in height (one surface in front of another: a box's edge over
        # its top face) a blend is a height no surface has, which the tracers would
        # see as a sheet joining the two: there take the nearest source pixel instead
        jumps = _jumps(hs, alpha > 0, jump)
        near_jump = _resample(jumps[:, :, None], wy, wx)[:, :, 0] > 0
        iy, ix = np.argmax(wy, axis=1), np.argmax(wx, axis=1)
        nearest = hs[iy][:, ix]
        placed_h = np.where(near_jump, nearest, smooth)
        placed_h = np.where(a > 1e-6, placed_h * scale, 0.0).astype(np.float32)
    if C == 4:
        img[:, :, 3] = a
    return img.astype(np.float32), a.astype(np.float32), placed_h
