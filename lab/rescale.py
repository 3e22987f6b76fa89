"""A benchmark scene at another size: enlarged by an integer factor and cropped to
a non-square frame, with its camera, so that methods can be run on large images
and compared with the same scene at 256^2.

    big = rescaled(sample, factor=4, height=700)     # 1024 x 700 from a 256^2 sample

The cutout's outline is the bilinear enlargement of its coverage thresholded at
0.5 (smooth, not blocky); pixel heights are enlarged bilinearly (cutout heights
averaged over cutout pixels only) and multiplied by ``factor``; the ground-truth
darkness is enlarged bilinearly (so it is only as detailed as the 256^2 render).
Rows are cropped symmetrically about the cutout's and shadow's vertical centre
(slid inside the image, starting on a multiple of ``factor``); the camera keeps its focal length and horizontal field
of view (the crop is full-width, so the principal point stays centred) and moves
its horizon row with the crop. ``rows`` gives the crop's first row in the
enlarged image.
"""
from __future__ import annotations

import numpy as np


def _up(a, factor):
    from pixgraph_nodes.ops.resample import resize
    H, W = a.shape
    return resize(np.asarray(a, np.float32), (H * factor, W * factor))


def rescaled(sample: dict, factor: int = 4, height: int | None = None) -> dict:
    """A copy of ``sample`` (``prepared_sample``'s dict) enlarged ``factor`` times and
    cropped to ``height`` rows (default: all). Keys: mask (bool), fg_height,
    bg_height, shadow, bg_valid, camera, light, device, rows (first row kept)."""
    from pixgraph_nodes.ops.camera import Camera
    cam = sample["camera"]
    inside = sample["mask"].astype(np.float32)
    cover = _up(inside, factor)
    fg = np.where(sample["mask"], sample["fg_height"], 0.0)
    fg_up = np.where(cover > 1e-6, _up(fg, factor) / np.maximum(cover, 1e-6), 0.0) * factor
    out = {"mask": cover > 0.5, "bg_height": _up(sample["bg_height"], factor) * factor,
           "shadow": np.clip(_up(sample["shadow"], factor), 0, 1),
           "bg_valid": _up(sample["bg_valid"].astype(np.float32), factor) > 0.5}
    out["fg_height"] = np.where(out["mask"], fg_up, 0.0).astype(np.float32)
    Hb = cam.height * factor
    h = Hb if height is None else int(height)
    ys = np.nonzero(out["mask"].any(axis=1) | (out["shadow"] > 0.01).any(axis=1))[0]
    centre = 0.5 * (ys.min() + ys.max() + 1) if ys.size else Hb / 2
    y0 = factor * int(np.clip(round((centre - h / 2) / factor), 0, (Hb - h) // factor))
    for k in ("mask", "bg_height", "shadow", "bg_valid", "fg_height"):
        out[k] = out[k][y0:y0 + h]
    out["camera"] = Camera(cam.width * factor, h, cam.hfov, cam.horizon * factor - y0, cam.cam_height)
    out["light"], out["device"], out["rows"] = sample["light"], sample.get("device"), y0
    return out
