"""Several cutouts in one scene: merge their masks, pixel heights and colours so that
the shadow tracers (which take one occluder mask and height) see all of them and
each casts on the others."""
from __future__ import annotations

import numpy as np


def merge_cutouts(masks, heights, images=None, threshold: float = 0.5):
    """Merge cutouts placed in the same image.

    masks: sequence of (H, W) coverages; heights: matching (H, W) pixel heights [px];
    images: optional matching (H, W, C) premultiplied colours.
    Where cutouts overlap, the one whose *foot* row ``v + h`` is largest is in front:
    with a level camera a lower foot in the image is closer (depth
    ``D = f H_cam / (v + h - horizon)`` falls as the foot row grows), so the front
    cutout's height is the occluding surface at that pixel and its colour is on top.
    Returns ``(mask, height, image)``: mask = max of the masks, height of the front
    cutout (0 outside every mask), and the colours composited back to front with
    premultiplied over (None when no images were given).
    """
    masks = [np.asarray(m, dtype=np.float32) for m in masks]
    heights = [np.asarray(h, dtype=np.float32) for h in heights]
    if not masks or len(masks) != len(heights):
        raise ValueError("need the same number (>= 1) of masks and heights")
    shape = masks[0].shape
    for a in masks + heights:
        if a.shape != shape:
            raise ValueError(f"all masks and heights must be {shape[::-1]} (W, H), got {a.shape[::-1]}")
    v = np.arange(shape[0], dtype=np.float32)[:, None] + 0.5
    inside = np.stack([m > threshold for m in masks])
    foot = np.stack([np.where(i, v + h, -np.inf) for i, h in zip(inside, heights)])
    front = np.argmax(foot, axis=0)
    height = np.take_along_axis(np.stack(heights), front[None], 0)[0]
    height = np.where(inside.any(0), height, 0.0).astype(np.float32)
    mask = np.max(np.stack(masks), axis=0)
    image = None
    if images is not None:
        imgs = [np.asarray(i, dtype=np.float32) for i in images]
        if len(imgs) != len(masks):
            raise ValueError("need one image per mask")
        # back to front per pixel: sort the cutouts by foot row (absent ones first)
        order = np.argsort(foot, axis=0, kind="stable")
        C = imgs[0].shape[2]
        stack = np.stack(imgs)                        # (N, H, W, C)
        alphas = np.stack(masks)                      # (N, H, W)
        image = np.zeros(shape + (C,), np.float32)
        for k in range(len(imgs)):
            idx = order[k]
            col = np.take_along_axis(stack, idx[None, :, :, None], 0)[0]
            a = np.take_along_axis(alphas, idx[None], 0)[0]
            image = col + image * (1.0 - a[:, :, None])
    return mask.astype(np.float32), height, image
