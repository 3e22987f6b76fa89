"""Glossy reflections of large images at a proxy resolution, enlarged edge-aware.

A glossy reflection (GGX roughness > 0) is blurred by its lobe: away from the
contact it is as low-frequency as a soft shadow's penumbra, and its cost grows
with the pixels traced times the samples each takes. So, as the soft shadow
(``upsample.proxy_soft_shadow``), an image whose longer side is over ``max_side``
is traced on a shrunken copy of the scene and enlarged with the numbers of
``upsample.masked_resize`` against the full-resolution mask (``enlarge_sparse``; the floor's
reflection and the cutout are not mixed across its outline). A mirror
(roughness 0) is as sharp as the cutout and is traced at full size.

The copy is the same scene: the camera keeps its field of view (its focal
length and horizon row scale with the image), pixel heights scale with the rows,
so the 3D scene the tracer reconstructs is unchanged. Error against the full
trace: docs/reflection.md (``benchmarks/reflection_bench.py --proxy-errors``).
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .camera import Camera
from .reflection import reflection_cl
from .resample import Window, _axis_weights, nonzero_box, shrink_part
from .upsample import AUTO_MAX_SIDE, MIN_PROXY_THICKNESS, proxy_scene

__all__ = ["AUTO_MAX_SIDE", "proxy_reflection"]


def proxy_reflection(device, camera: Camera, cutout, fg_height, bg_height, *, max_side: int = AUTO_MAX_SIDE,
                     mask=None, thickness: float = 4.0, roughness: float = 0.0, receive=None, **kw) -> dict:
    """``reflection_cl`` of a large image traced at a proxy whose longer side is
    ``max_side`` px (roughness > 0 only; at or below ``max_side``, or a mirror, it
    is ``reflection_cl`` itself). ``thickness`` [image px] scales with the proxy
    (at least ``MIN_PROXY_THICKNESS`` proxy px); the other keywords go to
    ``reflection_cl``. ``receive``: float32 (H, W) weight in [0, 1] of the
    surfaces that reflect (None: all), applied to the layer at full resolution;
    pixels of weight 0 are not traced (at the proxy: proxy pixels with no
    receiving pixel under them), and the enlargement does not mix receivers with
    the rest across the receiver's outline.

    Returns its dict at full size: ``layer`` float32 (H, W, 4) premultiplied,
    ``spp`` and ``steps`` int32 (H, W) of the proxy pixel each pixel was enlarged
    from, ``proxy`` (h, w) the traced size.

    Full-resolution work is kept to what the reflection touches: the cutout is
    shrunk over its own box only, the enlargement and the receiver weight cover
    only the box the proxy's reflection reaches."""
    bg_height = np.asarray(bg_height, np.float32)
    H, W = bg_height.shape
    if max_side < 16:
        raise ValueError(f"a proxy needs a longer side of at least 16 px, got {max_side}")
    recv = None if receive is None else np.asarray(receive, np.float32)
    win = Window.whole(H, W, max_side)
    if roughness <= 0.0 or (win.out_h, win.out_w) == (H, W):
        r = reflection_cl(device, camera, cutout, fg_height, bg_height, mask=mask, thickness=thickness,
                          roughness=roughness, receive=None if recv is None else recv > 0, **kw)
        if recv is not None:
            _weigh(r["layer"], recv, _box_of(r["layer"]))
        return dict(r, proxy=(H, W))
    cutout = np.asarray(cutout, np.float32)
    m_full = np.asarray(cutout[..., 3] if mask is None else mask, np.float32)
    m, fg, bg = proxy_scene(win, m_full, fg_height, bg_height)
    h, w = win.out_h, win.out_w
    cut = shrink_in_box(cutout, (h, w))
    cam = dataclasses.replace(camera, width=w, height=h, horizon=camera.horizon * win.ky)
    side_lo, side_hi, receive_lo = m, m_full, None
    if recv is not None:
        # proxy pixels with a receiving pixel under them are traced; the enlargement
        # keeps the receivers on one side of the outline and the cutout and the
        # rest (a wall) on the other
        on = recv > 0
        frac = _block_mean(on, (h, w))
        receive_lo = _grow(frac > 0)
        side_lo = np.maximum(m, (frac < 0.5).astype(np.float32))
        side_hi = (m_full > 0.5) | ~on
    r = reflection_cl(device, cam, cut, fg, bg, mask=m, thickness=max(thickness * win.ky, MIN_PROXY_THICKNESS),
                      roughness=roughness, receive=receive_lo, **kw)
    layer = enlarge_sparse(r["layer"], side_lo, side_hi, (H, W), weight=recv)
    iy = np.minimum((np.arange(H) * h) // H, h - 1)
    ix = np.minimum((np.arange(W) * w) // W, w - 1)
    # columns on the small map, then whole rows (row copies are fast)
    return {"layer": layer, "spp": r["spp"][:, ix][iy], "steps": r["steps"][:, ix][iy], "proxy": (h, w)}


def enlarge_sparse(lo: np.ndarray, side_lo: np.ndarray, side_hi: np.ndarray, shape, weight=None,
                   tile: int = 128) -> np.ndarray:
    """Edge-aware enlargement of a mostly-empty (h, w, C) layer to ``shape`` (H, W):
    per channel the numbers of ``upsample.masked_resize(lo[..., c], side_lo, side_hi,
    shape)`` (each output pixel interpolates the proxy pixels on its own side of
    the outline, bilinear weights renormalised; plain bilinear where its side has
    none within reach), clipped at 0 and times ``weight`` (H, W) when given.

    Computed in ``tile`` x ``tile`` output tiles, all channels at once, and only
    for tiles whose proxy pixels are not all 0 (elsewhere the result is 0): a
    glossy reflection's sparse far samples would otherwise make its box the
    whole floor. float32 (H, W, C)."""
    lo = np.asarray(lo, np.float32)
    h, w, C = lo.shape
    H, W = (int(s_) for s_ in shape)
    out = np.zeros((H, W, C), np.float32)
    active = (lo != 0).any(axis=2)
    if not active.any():
        return out
    ridx, rwt = _axis_weights(h, H)
    cidx, cwt = _axis_weights(w, W)
    inside_lo = np.asarray(side_lo) > 0.5
    # integral image of the active proxy pixels: "any active in a block" in O(1)
    acc = np.pad(np.cumsum(np.cumsum(active, 0, dtype=np.int64), 1), ((1, 0), (1, 0)))
    for r0 in range(0, H, tile):
        r1 = min(H, r0 + tile)
        ri, rw = ridx[r0:r1], rwt[r0:r1]
        pr0, pr1 = int(ri.min()), int(ri.max()) + 1
        for c0 in range(0, W, tile):
            c1 = min(W, c0 + tile)
            ci, cw = cidx[c0:c1], cwt[c0:c1]
            pc0, pc1 = int(ci.min()), int(ci.max()) + 1
            if acc[pr1, pc1] - acc[pr0, pc1] - acc[pr1, pc0] + acc[pr0, pc0] == 0:
                continue
            sub = lo[pr0:pr1, pc0:pc1]
            s_lo = inside_lo[pr0:pr1, pc0:pc1]
            hi_in = np.asarray(side_hi[r0:r1, c0:c1]) > 0.5
            one_side = (not s_lo.any() and not hi_in.any()) or (s_lo.all() and hi_in.all())
            if one_side:
                # no outline within reach: every weight is on the pixel's own side,
                # so the renormalised interpolation is the plain one (den = 1)
                cols = np.einsum("rotp,ot->rop", sub[:, ci - pc0], cw)
                res = np.einsum("otcp,ot->ocp", cols[ri - pr0], rw)
            else:
                s_in = s_lo[..., None].astype(np.float32)
                s_out = 1.0 - s_in
                planes = np.concatenate([sub, s_out, sub * s_out, s_in, sub * s_in], axis=2)   # (pr, pc, 3C + 2)
                cols = np.einsum("rotp,ot->rop", planes[:, ci - pc0], cw)
                full = np.einsum("otcp,ot->ocp", cols[ri - pr0], rw)                          # (nr, nc, 3C + 2)
                res = full[..., :C]
                for k, here in ((C, ~hi_in), (2 * C + 1, hi_in)):
                    den = full[..., k]
                    ok = here & (den > 1e-3)
                    res[ok] = full[..., k + 1:k + 1 + C][ok] / den[ok][:, None]
            np.maximum(res, 0.0, out=res)       # bilinear weights are >= 0; only rounding dips below
            if weight is not None:
                res *= np.asarray(weight[r0:r1, c0:c1], np.float32)[..., None]
            out[r0:r1, c0:c1] = res
    return out


def _box_of(layer):
    """(r0, r1, c0, c1) of the pixels of an (H, W, 4) layer that are not all 0, or None."""
    nz = layer[..., 3] != 0
    nz |= (layer[..., :3] != 0).any(axis=2)
    return nonzero_box(nz)


def _weigh(layer, recv, box) -> None:
    """layer *= recv over ``box`` (in place); outside it the layer is 0."""
    if box is None:
        return
    r0, r1, c0, c1 = box
    layer[r0:r1, c0:c1] *= recv[r0:r1, c0:c1, None]


def _edges(n_in: int, n_out: int) -> np.ndarray:
    """First input index of each output pixel's footprint (n_out,): a partition of the input."""
    return (np.arange(n_out, dtype=np.int64) * n_in) // n_out


def _block_mean(a: np.ndarray, shape) -> np.ndarray:
    """Mean of bool/float ``a`` (H, W) over each output pixel's footprint, float32 ``shape``."""
    H, W = a.shape
    h, w = shape
    re, ce = _edges(H, h), _edges(W, w)
    s = np.add.reduceat(np.add.reduceat(a.astype(np.float32), re, axis=0), ce, axis=1)
    n = np.diff(np.append(re, H))[:, None] * np.diff(np.append(ce, W))[None, :]
    return (s / n).astype(np.float32)


def _grow(a: np.ndarray) -> np.ndarray:
    """``a`` (bool) dilated by one pixel (3x3): the bilinear enlargement reads the neighbours."""
    g = np.pad(a, 1)
    out = a.copy()
    for di in (0, 1, 2):
        for dj in (0, 1, 2):
            out |= g[di:di + a.shape[0], dj:dj + a.shape[1]]
    return out


def shrink_in_box(image: np.ndarray, shape) -> np.ndarray:
    """``resample.resize`` of each channel of ``image`` (H, W, C) to ``shape``, computed
    only where it can differ from 0: over the output pixels whose bilinear taps
    reach the box of the image's nonzero pixels (a placed cutout covers a small
    part of a photo). Same numbers as resizing the whole image. float32 (h, w, C)."""
    image = np.asarray(image, np.float32)
    nz = (image != 0).any(axis=2)
    box = nonzero_box(nz)
    if box is None:
        return np.zeros(tuple(int(s_) for s_ in shape) + (image.shape[2],), np.float32)
    r0, r1, c0, c1 = box
    return shrink_part(image[r0:r1, c0:c1], (r0, c0), image.shape[:2], shape)

