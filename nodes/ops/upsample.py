"""Soft shadows of large images at a proxy resolution, upsampled edge-aware.

A soft shadow is low-frequency away from contact: its penumbra is as wide as
the light's angular size times the occluder-receiver distance. So a large
image's soft shadow can be traced on a shrunken copy of the scene (the
*proxy*, ``resample.Window.whole``) and enlarged again. What must stay sharp
is the cutout's outline: the shadow on the background and the self-shadow on
the cutout are different surfaces, and a plain bilinear enlargement would
bleed one into the other across the outline (a grey halo around the cutout,
or lit seams inside it). :func:`masked_resize` is a joint bilateral upsample
whose range kernel is the full-resolution mask: each full-resolution pixel
interpolates only the proxy pixels on its own side of the outline
(normalised convolution with bilinear weights).

Accuracy and speed against the full-resolution soft shadow are measured by
``benchmarks/proxy_bench.py`` (docs/auto.md).
"""
from __future__ import annotations

import numpy as np

from .bands import for_bands
from .memo import FrozenMemo
from .resample import Window, _axis_weights, nonzero_box, resize, shrink, shrink_part
from .shadow import soft_shadow

#: proxy scenes of frozen full-size inputs (ops/memo.py): a light sweep or drag traces
#: the same mask and heights again and again
_SCENES = FrozenMemo(size=2)

#: ``proxy="auto"``: images whose longer side is at most this are traced at
#: full resolution; larger ones at a proxy of this longer side (docs/auto.md
#: has the error this costs).
AUTO_MAX_SIDE = 1024


#: thinnest occluder [proxy px] traced on a proxy: with the thickness scaled
#: down below one proxy pixel, rays slip between the proxy's samples (4 wall
#: scenes at 1024^2, 64 samples, 256-px proxy: RMSE against the full trace
#: 0.030 with 0.25 px, 0.010 with 1 px; benchmarks/proxy_bench.py)
MIN_PROXY_THICKNESS = 1.0


def masked_resize(lo: np.ndarray, mask_lo: np.ndarray, mask_hi: np.ndarray, shape, band: int = 256,
                  box=None, return_lost: bool = False):
    """Resize ``lo`` (h, w) to ``shape`` (H, W), not mixing across the cutout's outline.

    mask_lo (h, w) and mask_hi (H, W): the cutout (> 0.5) at both resolutions.
    A pixel outside ``mask_hi`` is the bilinear average of the ``lo`` pixels
    outside ``mask_lo`` (weights renormalised), a pixel inside of those inside;
    where no such pixel is within reach (a gap thinner than a proxy pixel) it
    falls back to the plain bilinear value. Returns float32 (H, W), or with
    ``box = (r0, r1, c0, c1)`` (output pixels) only that part of it.

    The columns are resized first on the small image (five (h, W) planes), then
    the output is made ``band`` rows at a time, so besides the result only a
    band's temporaries are held at full resolution (a 4096^2 output no longer
    needs a dozen full-size float arrays).

    ``return_lost``: returns ``(out, lost)``, ``lost`` (bool, out's shape) the pixels
    inside ``mask_hi`` with no ``lo`` pixel inside ``mask_lo`` within reach (those
    given the plain bilinear value: a part of the cutout thinner than a ``lo`` pixel).
    """
    lo = np.asarray(lo, np.float32)
    H, W = (int(s) for s in shape)
    h, w = lo.shape
    r0b, r1b, c0b, c1b = (0, H, 0, W) if box is None else (int(b) for b in box)
    if h == H:
        idx, wts = np.arange(H)[:, None], np.ones((H, 1), np.float32)
    else:
        idx, wts = _axis_weights(h, H)
    # only the rows of `lo` the box's output rows read
    q0, q1 = int(idx[r0b:r1b].min()), int(idx[r0b:r1b].max()) + 1
    idx = idx - q0
    lo = lo[q0:q1]
    inside_lo = np.asarray(mask_lo)[q0:q1] > 0.5
    sides = [s for s in (~inside_lo, inside_lo) if s.any()]
    planes = [lo]
    for side in sides:
        wgt = side.astype(np.float32)
        planes += [wgt, lo * wgt]
    if w == W:
        cols = [p_[:, c0b:c1b] for p_ in planes]
    else:
        cidx, cwt = _axis_weights(w, W)
        cidx, cwt = cidx[c0b:c1b], cwt[c0b:c1b]
        cols = [np.einsum("rot,ot->ro", p_[:, cidx], cwt) for p_ in planes]      # (q1 - q0, c1 - c0) each
    out = np.empty((r1b - r0b, c1b - c0b), np.float32)
    lost = np.zeros(out.shape, bool) if return_lost else None

    def band_rows(r0, r1):
        ix, wt = idx[r0:r1], wts[r0:r1]

        def rows(c):
            return np.einsum("rtx,rt->rx", c[ix], wt)
        res = rows(cols[0])
        inside_hi = np.asarray(mask_hi[r0:r1, c0b:c1b]) > 0.5
        for k, side in enumerate(sides):
            side_hi = inside_hi if side is inside_lo else ~inside_hi
            if not side_hi.any():
                continue
            den, num = rows(cols[1 + 2 * k]), rows(cols[2 + 2 * k])
            ok = side_hi & (den > 1e-3)
            res[ok] = num[ok] / den[ok]
            if lost is not None and side is inside_lo:
                lost[r0 - r0b:r1 - r0b] = side_hi & ~ok
        if lost is not None and not any(side is inside_lo for side in sides):
            lost[r0 - r0b:r1 - r0b] = inside_hi
        out[r0 - r0b:r1 - r0b] = res
    for_bands(band_rows, r0b, r1b, band)        # on the machine's cores (ops/bands.py)
    return (out, lost) if return_lost else out


def support_box(active_lo: np.ndarray, shape, pad: int = 2):
    """The output pixels (r0, r1, c0, c1) of an enlargement to ``shape`` (H, W) that
    may depend on the True pixels of ``active_lo`` (h, w) (bilinear support, ``pad``
    proxy pixels of margin), or None when none is True: everywhere else the
    enlargement of a map that is constant outside them is that constant."""
    rows = np.flatnonzero(active_lo.any(axis=1))
    if len(rows) == 0:
        return None
    cols = np.flatnonzero(active_lo.any(axis=0))
    h, w = active_lo.shape
    H, W = shape
    a, b = max(0, rows[0] - pad), min(h, rows[-1] + 1 + pad)
    c, d = max(0, cols[0] - pad), min(w, cols[-1] + 1 + pad)
    return (max(0, int(np.floor(a * H / h))), min(H, int(np.ceil(b * H / h))),
            max(0, int(np.floor(c * W / w))), min(W, int(np.ceil(d * W / w))))


def cutout_scene(win: Window, mask, fg_height, within=None):
    """The cutout's half of ``win.scene`` of a whole-image window: (mask, fg_height)
    at (out_h, out_w), the same numbers, resized only over the cutout's box (the
    two maps are zero off it, and a cutout covers a small part of a 20 MP photo;
    ``resample.shrink_part``). Heights in proxy pixels. ``within``: (r0, r1, c0, c1)
    a box the caller knows holds every pixel of ``mask > 0.5`` (e.g. the nonzero
    box of a cutout whose alpha is the mask): only it is searched."""
    mask = np.asarray(mask)
    H, W = mask.shape
    h, w = win.out_h, win.out_w
    a0, a1, b0, b1 = (0, H, 0, W) if within is None else within
    inside = mask[a0:a1, b0:b1] > 0.5
    box = nonzero_box(inside)
    if box is None:
        return np.zeros((h, w), np.float32), np.zeros((h, w), np.float32)
    r0, r1, c0, c1 = box[0] + a0, box[1] + a0, box[2] + b0, box[3] + b0
    ins = inside[r0 - a0:r1 - a0, c0 - b0:c1 - b0]
    fg = np.where(ins, np.nan_to_num(np.asarray(fg_height[r0:r1, c0:c1], np.float32)), 0.0)
    part = np.stack([ins.astype(np.float32), fg.astype(np.float32)], axis=2)
    cover, fg_sum = np.moveaxis(shrink_part(part, (r0, c0), (H, W), (h, w)), 2, 0)
    m = (cover > 0.5).astype(np.float32)
    fg_w = np.where(cover > 1e-6, fg_sum / np.maximum(cover, 1e-6), 0.0) * win.ky * m
    return m, fg_w.astype(np.float32)


def proxy_scene(win: Window, mask, fg_height, bg_height, within=None):
    """``win.scene(mask, fg_height, bg_height)`` of a whole-image window (``Window.whole``):
    the cutout's coverage and height as :func:`cutout_scene` (the same numbers;
    ``within`` as there), the background's height rows first (``resample.shrink``),
    the same up to float rounding.

    Returns (mask, fg_height, bg_height) at (out_h, out_w), heights in proxy pixels."""
    H, W = np.shape(mask)
    if (win.x0, win.y0, win.w, win.h) != (0, 0, W, H):
        raise ValueError(f"proxy_scene takes a whole-image window, got {win} for {W}x{H}")
    m, fg_w = cutout_scene(win, mask, fg_height, within)
    return m, fg_w, proxy_bg_height(win, bg_height)


def proxy_bg_height(win: Window, bg_height) -> np.ndarray:
    """The background's height of ``win.scene`` of a whole-image window, in proxy pixels
    (non-finite values as 0), shrunk rows first (``resample.shrink``): the same up
    to float rounding."""
    bg = np.asarray(bg_height, np.float32)
    if not np.isfinite(bg.min() + bg.max()):      # one pass each; nan_to_num only when needed
        bg = np.nan_to_num(bg, nan=0.0, posinf=0.0, neginf=0.0)
    return (shrink(bg, (win.out_h, win.out_w)) * win.ky).astype(np.float32)


def proxy_soft_shadow_parts(device, mask, fg_height, bg_height, light_samples, thickness=1.0,
                            max_side: int = AUTO_MAX_SIDE, *, progress=None, check_cancelled=None):
    """:func:`proxy_soft_shadow` as parts: ``(full, box, part)``. At or below
    ``max_side`` ``full`` is the whole lit fraction (H, W) and ``box``, ``part``
    are None; above it ``full`` is None and the image is fully lit (1) except in
    ``box`` = (r0, r1, c0, c1), where it is ``part`` (None when nothing is shadowed).
    The proxy scene of frozen inputs is remembered (``_SCENES``)."""
    mask = np.asarray(mask)
    H, W = mask.shape
    if max_side < 16:
        raise ValueError(f"a proxy needs a longer side of at least 16 px, got {max_side}")
    win = Window.whole(H, W, max_side)
    if (win.out_h, win.out_w) == (H, W):
        return soft_shadow(device, mask, fg_height, bg_height, light_samples, thickness,
                           progress=progress, check_cancelled=check_cancelled), None, None
    inputs = (mask, fg_height, bg_height)
    scene = _SCENES.get(inputs, (H, W, max_side))
    if scene is None:
        scene = proxy_scene(win, mask, fg_height, bg_height)
        for a in scene:
            a.flags.writeable = False
        _SCENES.put(inputs, (H, W, max_side), scene)
    m, fg, bg = scene
    lit = soft_shadow(device, m, fg, bg, win.light_points(light_samples),
                      max(thickness * win.ky, MIN_PROXY_THICKNESS), progress=progress,
                      check_cancelled=check_cancelled)
    box = support_box(lit < 1.0, (H, W))
    if box is None:
        return None, None, None
    part = masked_resize(lit, m, mask, (H, W), box=box)
    return None, box, np.clip(part, 0.0, 1.0, out=part)


def proxy_soft_shadow(device, mask, fg_height, bg_height, light_samples, thickness=1.0,
                      max_side: int = AUTO_MAX_SIDE, *, progress=None, check_cancelled=None) -> np.ndarray:
    """Lit fraction float32 (H, W) of :func:`shadow.soft_shadow`, traced on a copy of
    the scene whose longer side is ``max_side`` pixels and enlarged with
    :func:`masked_resize`. ``thickness`` is in image pixels, scaled with the
    proxy but never below ``MIN_PROXY_THICKNESS`` proxy pixels. At or below
    ``max_side`` it is exactly ``soft_shadow``. progress, check_cancelled: as
    ``soft_shadow``'s (banded trace)."""
    return lit_and_darkness(*proxy_soft_shadow_parts(
        device, mask, fg_height, bg_height, light_samples, thickness, max_side, progress=progress,
        check_cancelled=check_cancelled), np.shape(mask), darkness=False)[0]


def lit_and_darkness(full, box, part, shape, darkness: bool = True):
    """(lit, darkness = 1 - lit) float32 (H, W) from :func:`proxy_soft_shadow_parts`'
    ``(full, box, part)``; outside the box only the lit array is written (the
    darkness is a fresh zero array: the system hands its pages over zeroed), so a
    20-megapixel shadow costs one full-size fill, not two and a subtraction.
    ``darkness=False``: (lit, None)."""
    if full is not None:
        return full, (np.subtract(np.float32(1.0), full, dtype=np.float32) if darkness else None)
    lit = np.ones(shape, np.float32)
    dark = np.zeros(shape, np.float32) if darkness else None
    if box is not None:
        r0, r1, c0, c1 = box
        lit[r0:r1, c0:c1] = part
        if darkness:
            np.subtract(np.float32(1.0), part, out=dark[r0:r1, c0:c1])
    return lit, dark
