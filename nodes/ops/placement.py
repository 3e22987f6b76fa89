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

from .bands import for_bands
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


def _taps(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Dense weights (n_out, n_src) as taps: ``idx``, ``wts`` (n_out, K), each row's
    span of nonzero weights from its first (K = the widest span; taps past a row's
    span have weight 0). A triangle filter reaches 2 source pixels when enlarging,
    about 2 / s when shrinking by s: K is small whatever the sizes."""
    nz = w != 0
    some = nz.any(axis=1)
    lo = np.where(some, nz.argmax(axis=1), 0)
    hi = np.where(some, w.shape[1] - nz[:, ::-1].argmax(axis=1), 0)
    K = max(1, int((hi - lo).max()))
    idx = lo[:, None] + np.arange(K)
    wts = np.take_along_axis(np.pad(w, ((0, 0), (0, K))), idx, axis=1)
    return np.minimum(idx, w.shape[1] - 1), wts


def _resample(planes: np.ndarray, wy: np.ndarray, wx: np.ndarray, band: int = 256) -> np.ndarray:
    """(h, w, C) -> (len(wy), len(wx), C) with separable weights (``planes @`` the dense
    weights on each axis, computed as taps: ``_taps``, in float64); only the canvas rows
    and columns the cutout reaches are computed, ``band`` canvas rows at a time on the
    machine's cores (ops/bands.py)."""
    out = np.zeros((wy.shape[0], wx.shape[0], planes.shape[2]), np.float32)
    rows = np.nonzero(wy.any(axis=1))[0]
    cols = np.nonzero(wx.any(axis=1))[0]
    if len(rows) == 0 or len(cols) == 0:
        return out
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    iy, ay = _taps(wy[r0:r1])
    ix, ax = _taps(wx[c0:c1])
    p = [planes[:, :, c] for c in range(planes.shape[2])]     # float32: a tap times its float64 weight is float64

    def rows(b0, b1):
        for c, pc in enumerate(p):
            t = ay[b0:b1, :1] * pc[iy[b0:b1, 0]]            # the band's rows: (b1 - b0, w)
            for k in range(1, iy.shape[1]):
                t += ay[b0:b1, k:k + 1] * pc[iy[b0:b1, k]]
            acc = t[:, ix[:, 0]] * ax[:, 0]                  # its columns: (b1 - b0, c1 - c0)
            for k in range(1, ix.shape[1]):
                acc += t[:, ix[:, k]] * ax[:, k]
            out[r0 + b0:r0 + b1, c0:c1, c] = acc
    for_bands(rows, 0, r1 - r0, band)
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


def is_hard_mask(alpha: np.ndarray) -> bool:
    """True when a mask has (almost) no soft edge: fewer values strictly between
    0.02 and 0.98 than a tenth of its outline's pixels (an antialiased matte has
    about one per outline pixel). Such a mask enlarged bilinearly shows its pixel
    staircase."""
    a = np.asarray(alpha, np.float32)
    inside = a > 0.5
    outline = int((inside[1:, :] != inside[:-1, :]).sum() + (inside[:, 1:] != inside[:, :-1]).sum())
    soft = int(((a > 0.02) & (a < 0.98)).sum())
    return outline > 0 and soft < 0.1 * outline


def _extend_nearest(values: np.ndarray, valid: np.ndarray, steps: int = 3) -> np.ndarray:
    """Extend (h, w) ``values`` from the ``valid`` pixels outward by ``steps`` pixels,
    each new pixel copying one valid neighbour (same row first, then column, then
    diagonals: an upright surface's row neighbours have its height):
    no blend of two surfaces, unlike :func:`_bleed`."""
    out = np.where(valid, values, 0.0).astype(np.float32)
    ok = np.asarray(valid, bool).copy()
    offsets = ((0, -1), (0, 1), (-1, 0), (1, 0), (-1, -1), (-1, 1), (1, -1), (1, 1))
    for _ in range(steps):
        if ok.all():
            break
        po, pk = np.pad(out, 1), np.pad(ok, 1)
        h, w = ok.shape
        new_out, new_ok = out.copy(), ok.copy()
        for dy, dx in offsets:
            take = ~new_ok & pk[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
            new_out[take] = po[1 + dy:1 + dy + h, 1 + dx:1 + dx + w][take]
            new_ok |= take
        out, ok = new_out, new_ok
    return out


def _blur(a: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur (radius 3 sigma, zero padding) of a float32 (h, w) map."""
    r = max(1, int(np.ceil(3.0 * sigma)))
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sigma) ** 2)
    k = (k / k.sum()).astype(np.float32)
    p = np.pad(np.asarray(a, np.float32), r)
    rows = sum(k[i] * p[i:i + a.shape[0], :] for i in range(2 * r + 1))
    return sum(k[i] * rows[:, i:i + a.shape[1]] for i in range(2 * r + 1)).astype(np.float32)


def _bleed(planes: np.ndarray, valid: np.ndarray, steps: int = 3) -> np.ndarray:
    """Extend (h, w, C) values from the ``valid`` pixels outward by ``steps`` pixels
    (each new pixel: the mean of its valid 8-neighbours), so that resampling near
    the outline never mixes in the undefined values outside it."""
    out = np.where(valid[:, :, None], planes, 0.0).astype(np.float32)
    ok = valid.copy()
    for _ in range(steps):
        p = np.pad(out, ((1, 1), (1, 1), (0, 0)))
        w = np.pad(ok, 1).astype(np.float32)
        h, wd = ok.shape
        acc = np.zeros_like(out)
        cnt = np.zeros((h, wd), np.float32)
        for dy in range(3):
            for dx in range(3):
                if dy == dx == 1:
                    continue
                acc += p[dy:dy + h, dx:dx + wd] * w[dy:dy + h, dx:dx + wd, None]
                cnt += w[dy:dy + h, dx:dx + wd]
        new = ~ok & (cnt > 0)
        out[new] = acc[new] / cnt[new, None]
        ok |= new
    return out


def smooth_outline(field: np.ndarray) -> np.ndarray:
    """Coverage of the region ``field > 0.5`` of a smooth field (H, W) sampled at
    pixel centres: ``clip(0.5 + d, 0, 1)`` with ``d = (field - 0.5) / |grad field|``
    the signed distance [px] to the 0.5 contour (first order), the coverage of a
    pixel cut by a straight edge at that distance. Where the field is flat it is
    0 or 1."""
    gy, gx = np.gradient(field)
    g = np.sqrt(gx * gx + gy * gy)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = (field - 0.5) / g
    d = np.where(g > 1e-6, d, np.where(field > 0.5, 1.0, -1.0))
    return np.clip(0.5 + d, 0.0, 1.0).astype(np.float32)


#: blur [source px] of a hard mask before it is enlarged: the contour of the
#: blurred mask is smooth. Measured on disks of radius 20 and 13 px enlarged 4x
#: (tests/test_placement.py): the RMS distance of the outline from the true circle
#: falls from 0.87 canvas px (bilinear) to 0.61 / 0.44 / 0.27 with 0.7 / 1.0 / 1.5,
#: but a blur shrinks small shapes (area -2 % at radius 7.7 px with 1.0, -4 % with 1.5)
HARD_EDGE_SIGMA = 1.0


def place_cutout(image: np.ndarray, alpha: np.ndarray, height: np.ndarray | None,
                 canvas: tuple[int, int], foot, scale: float = 1.0, flip: bool = False,
                 anchor=None, jump: float = 4.0, smooth_edge: bool = False):
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

    smooth_edge: a hard (binary, ``is_hard_mask``) mask enlarged (scale > 1) gets
    a clean antialiased outline instead of its pixel staircase: the mask is
    blurred by ``HARD_EDGE_SIGMA`` source px, enlarged, and the 0.5 contour of that
    smooth field is drawn one canvas pixel wide (``smooth_outline``); colour and
    heights are extended past the outline before resampling, so the new edge
    pixels get the cutout's own colour and heights.
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
    C = image.shape[2]
    # the work is done on the box of canvas rows and columns the cutout reaches (a
    # cutout covers a part of a 20 MP photo), then put on an empty canvas
    rows, cols = np.flatnonzero(wy.any(axis=1)), np.flatnonzero(wx.any(axis=1))
    if len(rows) == 0 or len(cols) == 0:
        return (np.zeros((H, W, C), np.float32), np.zeros((H, W), np.float32),
                None if height is None else np.zeros((H, W), np.float32))
    r0, r1, c0, c1 = rows[0], rows[-1] + 1, cols[0], cols[-1] + 1
    img_b, a_b, h_b = _place_box(image, alpha, height, wy[r0:r1], wx[c0:c1], scale, jump,
                                 smooth_edge and scale > 1.0 and is_hard_mask(alpha))
    img = np.zeros((H, W, C), np.float32)
    a = np.zeros((H, W), np.float32)
    img[r0:r1, c0:c1], a[r0:r1, c0:c1] = img_b, a_b
    placed_h = None
    if h_b is not None:
        placed_h = np.zeros((H, W), np.float32)
        placed_h[r0:r1, c0:c1] = h_b
    return img, a, placed_h


def _place_box(image, alpha, height, wy, wx, scale, jump, refine):
    """``place_cutout`` on the canvas box whose resampling weights are ``wy``, ``wx``."""
    planes = [image, alpha[:, :, None]]
    if height is not None:
        # the heights belong to the occluder (alpha > 0.5, as CutoutHeight and the
        # tracers read a mask): carried from it onto the partly covered pixels
        # around it, which would otherwise pull the outline's heights toward 0
        height = _extend_nearest(np.asarray(height, dtype=np.float32), alpha > 0.5)
        planes.append((height * alpha)[:, :, None])
    C = image.shape[2]
    if refine:
        # straight colour (and height) extended past the outline, resampled, then
        # premultiplied by the new coverage
        inside = alpha > 0.5
        ncol = C - 1 if C in (2, 4) else C
        src = [image[:, :, :ncol] / np.maximum(alpha, 1e-6)[:, :, None]]
        if height is not None:
            src.append(np.asarray(height, np.float32)[:, :, None])
        src.append(_blur(inside.astype(np.float32), HARD_EDGE_SIGMA)[:, :, None])
        bled = np.concatenate(src, axis=2)
        bled[:, :, :-1] = _bleed(bled[:, :, :-1], inside)
        res = _resample(bled, wy, wx)
        a = smooth_outline(res[:, :, -1])
        img = np.empty(res.shape[:2] + (C,), np.float32)
        img[:, :, :ncol] = res[:, :, :ncol] * a[:, :, None]
        if ncol < C:
            img[:, :, ncol] = a
        out = np.concatenate([img, a[:, :, None], (res[:, :, ncol:ncol + 1] * a[:, :, None]
                                                   if height is not None else a[:, :, None] * 0)], axis=2)
    else:
        out = _resample(np.concatenate(planes, axis=2), wy, wx)
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
