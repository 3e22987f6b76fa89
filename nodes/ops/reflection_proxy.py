"""Glossy reflections of large images at a proxy resolution, enlarged edge-aware.

A glossy reflection (GGX roughness > 0) is blurred by its lobe: away from the
contact it is as low-frequency as a soft shadow's penumbra, and its cost grows
with the pixels traced times the samples each takes. So, as the soft shadow
(``upsample.proxy_soft_shadow``), an image whose longer side is over ``max_side``
is traced on a shrunken copy of the scene and enlarged with
``upsample.masked_resize`` against the full-resolution mask (the floor's
reflection and the cutout are not mixed across its outline). A mirror
(roughness 0) is as sharp as the cutout and is traced at full size.

The copy is the same scene: the camera keeps its field of view (its focal
length and horizon row scale with the image), pixel heights scale with the rows,
so the 3D scene the tracer reconstructs is unchanged. Error against the full
trace: docs/reflection.md (``benchmarks/photo_bench.py --errors``).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .camera import Camera
from .reflection import reflection_cl
from .resample import Window, resize
from .upsample import AUTO_MAX_SIDE, MIN_PROXY_THICKNESS, masked_resize, support_box

__all__ = ["AUTO_MAX_SIDE", "proxy_reflection"]


def proxy_reflection(device, camera: Camera, cutout, fg_height, bg_height, *, max_side: int = AUTO_MAX_SIDE,
                     mask=None, thickness: float = 4.0, roughness: float = 0.0, **kw) -> dict:
    """``reflection_cl`` of a large image traced at a proxy whose longer side is
    ``max_side`` px (roughness > 0 only; at or below ``max_side``, or a mirror, it
    is ``reflection_cl`` itself). ``thickness`` [image px] scales with the proxy
    (at least ``MIN_PROXY_THICKNESS`` proxy px); the other keywords go to
    ``reflection_cl``. Returns its dict at full size: ``layer`` float32 (H, W, 4)
    premultiplied, ``spp`` and ``steps`` int32 (H, W) of the proxy pixel each
    pixel was enlarged from, ``proxy`` (h, w) the traced size."""
    bg_height = np.asarray(bg_height, np.float32)
    H, W = bg_height.shape
    if max_side < 16:
        raise ValueError(f"a proxy needs a longer side of at least 16 px, got {max_side}")
    win = Window.whole(H, W, max_side)
    if roughness <= 0.0 or (win.out_h, win.out_w) == (H, W):
        r = reflection_cl(device, camera, cutout, fg_height, bg_height, mask=mask, thickness=thickness,
                          roughness=roughness, **kw)
        return dict(r, proxy=(H, W))
    cutout = np.asarray(cutout, np.float32)
    m_full = np.asarray(cutout[..., 3] if mask is None else mask, np.float32)
    m, fg, bg = win.scene(m_full, fg_height, bg_height)
    h, w = win.out_h, win.out_w
    cut = np.empty((h, w, 4), np.float32)
    for c in range(4):                     # premultiplied colour and alpha resize linearly
        cut[:, :, c] = resize(np.ascontiguousarray(cutout[:, :, c]), (h, w))
    cam = dataclasses.replace(camera, width=w, height=h, horizon=camera.horizon * win.ky)
    r = reflection_cl(device, cam, cut, fg, bg, mask=m, thickness=max(thickness * win.ky, MIN_PROXY_THICKNESS),
                      roughness=roughness, **kw)
    layer = np.zeros((H, W, 4), np.float32)
    box = support_box((r["layer"] != 0).any(axis=2), (H, W))
    if box is not None:
        r0, r1, c0, c1 = box
        for c in range(4):
            layer[r0:r1, c0:c1, c] = masked_resize(r["layer"][:, :, c], m, m_full, (H, W), box=box)
        np.maximum(layer, 0.0, out=layer)     # bilinear weights are >= 0; only rounding can dip below
    iy = np.minimum((np.arange(H) * h) // H, h - 1)
    ix = np.minimum((np.arange(W) * w) // W, w - 1)
    return {"layer": layer, "spp": r["spp"][iy][:, ix], "steps": r["steps"][iy][:, ix],
            "proxy": (h, w)}
