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
from .resample import Window, _axis_weights, image_box, nonzero_pixels, shrink_part
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
    ``spp`` and ``steps`` float32 (H, W) (whole numbers: the node's stats) of the
    proxy pixel each pixel was enlarged from, ``proxy`` (h, w) the traced size.

    Full-resolution work is kept to what the reflection touches: the cutout is
    shrunk over its own box only (found from its bits, ``resample.image_box``), the
    enlargement and the receiver weight cover only the tiles the proxy's
    reflection reaches, the full-size maps it needs there (the receiver's side of
    the outline) are made per tile, and the banded steps run on the shared pool
    (ops/bands.py)."""
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
            _weigh(r["layer"], recv, image_box(r["layer"]))
        return dict(r, spp=r["spp"].astype(np.float32), steps=r["steps"].astype(np.float32), proxy=(H, W))
    cutout = np.asarray(cutout, np.float32)
    box = image_box(cutout)
    m_full = np.asarray(cutout[..., 3] if mask is None else mask, np.float32)
    # without a mask the cutout's alpha is 0 off the cutout's box: only the box is read
    m, fg, bg = proxy_scene(win, m_full, fg_height, bg_height, within=box if mask is None else None)
    h, w = win.out_h, win.out_w
    cut = shrink_in_box(cutout, (h, w), box) if box is not None else np.zeros((h, w, 4), np.float32)
    cam = dataclasses.replace(camera, width=w, height=h, horizon=camera.horizon * win.ky)
    side_lo, side_hi, receive_lo = m, m_full, None
    if recv is not None:
        # proxy pixels with a receiving pixel under them are traced; the enlargement
        # keeps the receivers on one side of the outline and the cutout and the
        # rest (a wall) on the other
        frac = _block_mean(recv > 0, (h, w))
        receive_lo = _grow(frac > 0)
        side_lo = np.maximum(m, (frac < 0.5).astype(np.float32))

        def side_hi(rows, cols):         # (m_full > 0.5) | ~(recv > 0), made per tile
            return (m_full[rows, cols] > 0.5) | ~(recv[rows, cols] > 0)
    r = reflection_cl(device, cam, cut, fg, bg, mask=m, thickness=max(thickness * win.ky, MIN_PROXY_THICKNESS),
                      roughness=roughness, receive=receive_lo, **kw)
    layer = enlarge_sparse(r["layer"], side_lo, side_hi, (H, W), weight=recv)
    return {"layer": layer, "spp": _nearest(r["spp"], (H, W)), "steps": _nearest(r["steps"], (H, W)),
            "proxy": (h, w)}


def _nearest(a: np.ndarray, shape) -> np.ndarray:
    """Nearest-neighbour enlargement of ``a`` (h, w) to ``shape`` (H, W): output pixel
    (i, j) is ``a[i h // H, j w // W]``, float32; the columns on the small map, then
    whole rows (one ``take`` into a fresh array: in bands, or through ``a[rows]``,
    its page faults cost several times more)."""
    h, w = a.shape
    H, W = (int(s_) for s_ in shape)
    iy = np.minimum((np.arange(H) * h) // H, h - 1)
    ix = np.minimum((np.arange(W) * w) // W, w - 1)
    out = np.empty((H, W), np.float32)
    np.take(np.asarray(a, np.float32)[:, ix], iy, axis=0, out=out, mode="clip")   # "raise" buffers `out`
    return out


def enlarge_sparse(lo: np.ndarray, side_lo: np.ndarray, side_hi, shape, weight=None,
                   tile: int = 128) -> np.ndarray:
    """Edge-aware enlargement of a mostly-empty (h, w, C) layer to ``shape`` (H, W):
    per channel the numbers of ``upsample.masked_resize(lo[..., c], side_lo, side_hi,
    shape)`` (each output pixel interpolates the proxy pixels on its own side of
    the outline, bilinear weights renormalised; plain bilinear where its side has
    none within reach), clipped at 0 and times ``weight`` (H, W) when given.
    ``side_hi`` and ``weight`` may also be functions of (row slice, column slice)
    that give that block of the map: only the tiles below need it.

    Computed in ``tile`` x ``tile`` output tiles, all channels at once, and only
    for tiles whose proxy pixels are not all 0 (elsewhere the result is 0): a
    glossy reflection's sparse far samples would otherwise make its box the
    whole floor. Rows of tiles run on the shared pool (ops/bands.py; the same
    numbers). float32 (H, W, C)."""
    from .bands import for_bands
    lo = np.asarray(lo, np.float32)
    h, w, C = lo.shape
    H, W = (int(s_) for s_ in shape)
    out = np.zeros((H, W, C), np.float32)
    active = nonzero_pixels(lo)
    if not active.any():
        return out
    ridx, rwt = _axis_weights(h, H)
    cidx, cwt = _axis_weights(w, W)
    inside_lo = np.asarray(side_lo) > 0.5
    hi_block = side_hi if callable(side_hi) else (lambda rows, cols: side_hi[rows, cols])
    wt_block = weight if weight is None or callable(weight) else (lambda rows, cols: weight[rows, cols])
    # integral image of the active proxy pixels: "any active in a block" in O(1)
    acc = np.pad(np.cumsum(np.cumsum(active, 0, dtype=np.int64), 1), ((1, 0), (1, 0)))

    def tile_row(r0, r1):
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
            hi_in = np.asarray(hi_block(slice(r0, r1), slice(c0, c1))) > 0.5
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
            dest = out[r0:r1, c0:c1]
            if wt_block is None:
                np.maximum(res, 0.0, out=dest)     # bilinear weights are >= 0; only rounding dips below
            else:
                np.maximum(res, 0.0, out=res)
                np.multiply(res, np.asarray(wt_block(slice(r0, r1), slice(c0, c1)), np.float32)[..., None],
                            out=dest)
    for_bands(tile_row, 0, H, tile)
    return out


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
    """Mean of bool ``a`` (H, W) over each output pixel's footprint (``_edges``; at most
    as many output pixels as input ones), float32 ``shape``. The footprints are
    counted in integers, rows then columns, one footprint offset at a time (each
    pass reads whole rows of bytes); output bands on the shared pool."""
    from .bands import for_bands
    u = np.ascontiguousarray(a, bool).view(np.uint8)
    H, W = u.shape
    h, w = (int(s_) for s_ in shape)
    re, ce = _edges(H, h), _edges(W, w)
    nr, nc = np.diff(np.append(re, H)), np.diff(np.append(ce, W))
    s = np.zeros((h, w), np.int64)

    def band(o0, o1):
        rows = np.zeros((o1 - o0, W), np.int32)
        n, first = nr[o0:o1], re[o0:o1]
        for j in range(int(n.max())):
            if n.min() > j:
                rows += u[first + j]
            else:
                sel = np.flatnonzero(n > j)
                rows[sel] += u[first[sel] + j]
        for j in range(int(nc.max())):
            if nc.min() > j:
                s[o0:o1] += rows[:, ce + j]
            else:
                sel = np.flatnonzero(nc > j)
                s[o0:o1, sel] += rows[:, ce[sel] + j]
    for_bands(band, 0, h, 64)
    return (s / (nr[:, None] * nc[None, :])).astype(np.float32)


def _grow(a: np.ndarray) -> np.ndarray:
    """``a`` (bool) dilated by one pixel (3x3): the bilinear enlargement reads the neighbours."""
    g = np.pad(a, 1)
    out = a.copy()
    for di in (0, 1, 2):
        for dj in (0, 1, 2):
            out |= g[di:di + a.shape[0], dj:dj + a.shape[1]]
    return out


def shrink_in_box(image: np.ndarray, shape, box=None) -> np.ndarray:
    """``resample.resize`` of each channel of ``image`` (H, W, C) to ``shape``, computed
    only where it can differ from 0: over the output pixels whose bilinear taps
    reach the box of the image's nonzero pixels (a placed cutout covers a small
    part of a photo; ``box``: ``resample.image_box(image)`` when known, else found).
    Same numbers as resizing the whole image. float32 (h, w, C)."""
    image = np.asarray(image, np.float32)
    if box is None:
        box = image_box(image)
    if box is None:
        return np.zeros(tuple(int(s_) for s_ in shape) + (image.shape[2],), np.float32)
    r0, r1, c0, c1 = box
    return shrink_part(image[r0:r1, c0:c1], (r0, c0), image.shape[:2], shape)
