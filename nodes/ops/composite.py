"""Compositing in linear light: apply a shadow to a background, then the cutout over it.

The math is numpy here (``composite_layers``, the reference) and OpenCL in
``composite.cl`` (``composite_layers_cl``, the same numbers bit for bit on a device
with IEEE float32 arithmetic); both work only over the boxes the shadow and the
layers touch.
"""
from __future__ import annotations

import numpy as np

from .bands import for_bands
from .memo import FrozenMemo
from .resample import image_box, nonzero_box

#: the box a frozen cutout touches (ops/memo.py): a light sweep composites the same cutout again and again
_BOXES = FrozenMemo(size=4)


def _hwc(a: np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float32)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3:
        raise ValueError(f"{name} must be (H, W) or (H, W, C), got shape {a.shape}")
    return a


def _shadow_plan(shape, darkness: np.ndarray, opacity: float, tint):
    """What ``apply_shadow`` needs, once: the darkness, the box where it is above 0
    (elsewhere the factor is exactly 1) and each colour channel's factor scale; None
    when nothing is shadowed."""
    d = np.asarray(darkness, dtype=np.float32)
    if d.shape != tuple(shape[:2]):
        raise ValueError(f"shadow is {d.shape[::-1]} but the background is {tuple(shape[1::-1])} (W, H)")
    box = nonzero_box(d > 0.0)
    if box is None or opacity == 0.0:
        return None
    ncol = 3 if shape[2] >= 3 else 1
    tint = np.asarray(tint, dtype=np.float32).reshape(-1)
    if tint.size == 1:
        tint = np.repeat(tint, ncol)
    t = tint[:ncol] if ncol == 3 else tint[:1]
    return d, box, [np.float32(-float(opacity) * (1.0 - float(t[c]))) for c in range(ncol)]


def _shadow_rows(out: np.ndarray, plan, r0: int, r1: int) -> None:
    """``apply_shadow`` in place on the rows [r0, r1) of ``out`` (H, W, C) float32."""
    d, (b0, b1, c0, c1), scales = plan
    r0, r1 = max(r0, b0), min(r1, b1)
    if r0 >= r1:
        return
    sub = np.clip(d[r0:r1, c0:c1], np.float32(0.0), np.float32(1.0))
    factor = np.empty_like(sub)
    for c, k in enumerate(scales):
        # bg * (1 - opacity * d * (1 - tint_c)), one channel at a time: no (H, W, 3) temporaries
        np.multiply(sub, k, out=factor)
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
    out = composite_layers(background, darkness, opacity, tint)
    return out.reshape(np.shape(background)) if np.ndim(background) == 2 else out


def _over_plan(shape, fg_premultiplied: np.ndarray, alpha: np.ndarray):
    """What ``over`` needs, once: the cutout, its coverage, the box where it has
    coverage or a channel != 0 (elsewhere the result is the background, exactly:
    ``bg * 1 + 0``; remembered for a frozen cutout, ``_BOXES``) and which of its
    channels go where; None when the cutout touches nothing."""
    fg = _hwc(fg_premultiplied, "cutout")
    a = np.asarray(alpha, dtype=np.float32)
    if fg.shape[:2] != tuple(shape[:2]) or a.shape != tuple(shape[:2]):
        raise ValueError(f"cutout {fg.shape[1::-1]}, alpha {a.shape[::-1]} and background "
                         f"{tuple(shape[1::-1])} must have the same size (W, H)")
    nf = min(fg.shape[2], 3)
    key = (fg_premultiplied, alpha)
    box = _BOXES.get(key)
    if box is None:
        box = _union(image_box(fg), None if _channel_of(a, fg) is not None else nonzero_box(a != 0.0)) or ()
        _BOXES.put(key, None, box)
    return (fg, a, box, nf) if box else None


def _union(*boxes):
    """The smallest (r0, r1, c0, c1) holding every box that is not None, or None."""
    boxes = [b for b in boxes if b]
    if not boxes:
        return None
    return (min(b[0] for b in boxes), max(b[1] for b in boxes), min(b[2] for b in boxes), max(b[3] for b in boxes))


def _channel_of(a: np.ndarray, fg: np.ndarray) -> int | None:
    """k when the coverage ``a`` (H, W) is channel k of ``fg`` (H, W, C), the same
    memory (a reflection layer's own alpha), else None."""
    if a.ndim != 2 or fg.ndim != 3 or a.strides != fg.strides[:2] or a.dtype != fg.dtype:
        return None
    k, rem = divmod(a.__array_interface__["data"][0] - fg.__array_interface__["data"][0], fg.itemsize)
    return k if rem == 0 and 0 <= k < fg.shape[2] and fg.strides[2] == fg.itemsize else None


def _over_rows(out: np.ndarray, plan, r0: int, r1: int) -> None:
    """``over`` in place on the rows [r0, r1) of ``out`` (the background, (H, W, C) float32)."""
    fg, a, (b0, b1, c0, c1), nf = plan
    r0, r1 = max(r0, b0), min(r1, b1)
    if r0 >= r1:
        return
    C = out.shape[2]
    ncol = 3 if C >= 3 else 1
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
    return composite_layers(background, layers=[(fg_premultiplied, alpha)])


def composite_layers(background, darkness=None, opacity: float = 1.0, tint=(0.0, 0.0, 0.0), layers=(),
                     band: int = 256) -> np.ndarray:
    """The background darkened by the shadow (``apply_shadow``; none when ``darkness``
    is None), then each ``(premultiplied colour, alpha)`` of ``layers`` over it in
    order (``over``), in one copy of the background (H, W, C) float32 made a band of
    ``band`` rows at a time on the machine's cores (ops/bands.py)."""
    bg = _hwc(background, "background")
    out = np.empty(bg.shape, np.float32)
    shadow = None if darkness is None else _shadow_plan(out.shape, darkness, opacity, tint)
    covers = [p for p in (_over_plan(out.shape, fg, a) for fg, a in layers) if p is not None]

    def rows(r0, r1):
        out[r0:r1] = bg[r0:r1]
        if shadow is not None:
            _shadow_rows(out, shadow, r0, r1)
        for cover in covers:
            _over_rows(out, cover, r0, r1)
    for_bands(rows, 0, out.shape[0], band)
    return out


def composite(background, cutout, alpha, darkness=None, opacity: float = 1.0, tint=(0.0, 0.0, 0.0)):
    """Shadow on the background (``apply_shadow``), then the cutout over it (``over``),
    in one copy of the background (``composite_layers``)."""
    return composite_layers(background, darkness, opacity, tint, [(cutout, alpha)])


#: the fewest pixels of a composite that go to the device (``device_for``): a
#: full-size final's (12-50 MP); a preview at working resolution (about 1 MP)
#: stays on the host, where it costs milliseconds
DEVICE_MIN_PIXELS = 4_000_000


def device_for(shape, open_device):
    """The OpenCL device a composite of a background of ``shape`` (H, W[, C]) runs
    on, or None for numpy (``composite_layers``): the device ``open_device()``
    returns (a node passes ``lambda: ctx.device``; called only for an image of
    ``DEVICE_MIN_PIXELS`` or more) when it is not a CPU. On a CPU device (PoCL) the
    host's own cores would do the same work after copying the boxes: measured a
    little slower than numpy there (benchmarks/composite_bench.py, docs/server.md,
    "On a GPU"). A composite needs no device: where none opens (no OpenCL
    platform, no pyopencl) it is numpy, and the nodes that do need one say why."""
    if int(shape[0]) * int(shape[1]) < DEVICE_MIN_PIXELS:
        return None
    try:
        import pyopencl as cl
        device = open_device()
        is_cpu = bool(device.queue.device.type & cl.device_type.CPU)
    except Exception:       # noqa: BLE001 - any failure to open one: the numpy path
        return None
    return None if is_cpu else device


#: work-group size (columns, rows) of the composite's kernels; the launches are
#: rounded up to it and the kernels skip the work items past the box
GROUP = (16, 16)


def _contiguous(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float32)


def _rect(queue, buf, host: np.ndarray, box, to_device: bool) -> None:
    """Copy the (r0, r1, c0, c1) ``box`` of the C-contiguous (H, W[, C]) ``host``
    array to (``to_device``) or from the buffer ``buf``, which holds that box alone,
    row-major (a blocking copy)."""
    import pyopencl as cl
    r0, r1, c0, c1 = box
    px = host.itemsize * (host.shape[2] if host.ndim == 3 else 1)
    kw = dict(buffer_origin=(0, 0), host_origin=(c0 * px, r0), region=((c1 - c0) * px, r1 - r0),
              buffer_pitches=((c1 - c0) * px,), host_pitches=(host.shape[1] * px,))
    if to_device:
        cl.enqueue_copy(queue, buf, host, **kw)
    else:
        cl.enqueue_copy(queue, host, buf, **kw)


def composite_layers_cl(device, background, darkness=None, opacity: float = 1.0, tint=(0.0, 0.0, 0.0),
                        layers=(), band: int = 256) -> np.ndarray:
    """``composite_layers`` on an OpenCL ``pixgraph.device.Device`` (kernels in
    ``composite.cl``): the background outside the union of the shadow's and the
    layers' boxes is copied on the host (a band of ``band`` rows at a time, ops/bands.py);
    that union box of it, and each input's own box, go to the device, and the
    union box comes back. Same arguments and result (float32 (H, W, C)) for finite
    inputs (the nodes check them first): the kernels clip with fmin/fmax, which
    turn a NaN coverage into 0 where numpy's clip keeps the NaN."""
    import pyopencl as cl
    from pixgraph.device import load_kernel_source

    bg = _contiguous(_hwc(background, "background"))
    H, W, C = bg.shape
    out = np.empty(bg.shape, np.float32)
    shadow = None if darkness is None else _shadow_plan(out.shape, darkness, opacity, tint)
    covers = [p for p in (_over_plan(out.shape, fg, a) for fg, a in layers) if p is not None]
    u = _union(shadow[1] if shadow is not None else None, *(p[2] for p in covers))
    U0, U1, V0, V1 = u if u is not None else (H, H, 0, 0)

    def rows(r0, r1):       # the background where nothing touches it
        if r1 <= U0 or r0 >= U1:
            out[r0:r1] = bg[r0:r1]
            return
        for a0, a1 in ((r0, U0), (U1, r1)):
            if a0 < a1:
                out[a0:a1] = bg[a0:a1]
        b0, b1 = max(r0, U0), min(r1, U1)
        out[b0:b1, :V0] = bg[b0:b1, :V0]
        out[b0:b1, V1:] = bg[b0:b1, V1:]
    for_bands(rows, 0, H, band)
    if u is None:
        return out
    ctx, queue = device.context, device.queue
    # IEEE division (a grey composite's mean of three), as numpy's, where the device has it
    exact = device.queue.device.single_fp_config & cl.device_fp_config.CORRECTLY_ROUNDED_DIVIDE_SQRT
    prg = device.program(load_kernel_source(__file__, "composite.cl"),
                         ("-cl-fp32-correctly-rounded-divide-sqrt",) if exact else ())
    mf = cl.mem_flags
    uw = V1 - V0
    obuf = cl.Buffer(ctx, mf.READ_WRITE, (U1 - U0) * uw * C * 4)
    _rect(queue, obuf, bg, u, True)
    ncol = 3 if C >= 3 else 1
    dims = np.int32(uw), np.int32(C), np.int32(ncol)

    def launch(knl, box, *args):     # one work item per pixel of ``box``, in groups of GROUP
        r0, r1, c0, c1 = box
        w, h = c1 - c0, r1 - r0
        size = tuple(-(-n // g) * g for n, g in zip((w, h), GROUP))
        knl(queue, size, GROUP, obuf, *dims, *args, np.int32(w), np.int32(h), np.int32(c0 - V0), np.int32(r0 - U0))
    if shadow is not None:
        d, box, scales = shadow
        d = _contiguous(d)
        r0, r1, c0, c1 = box
        dbuf = cl.Buffer(ctx, mf.READ_ONLY, (r1 - r0) * (c1 - c0) * 4)
        _rect(queue, dbuf, d, box, True)
        launch(cl.Kernel(prg, "shadow_box"), box, dbuf, *(np.float32(x) for x in (list(scales) + [0.0, 0.0])[:3]))
    for fg, a, box, nf in covers:
        r0, r1, c0, c1 = box
        fg = _contiguous(fg)
        n = (r1 - r0) * (c1 - c0)
        fbuf = cl.Buffer(ctx, mf.READ_ONLY, n * fg.shape[2] * 4)
        _rect(queue, fbuf, fg, box, True)
        k = _channel_of(a, fg)
        if k is None:
            abuf = cl.Buffer(ctx, mf.READ_ONLY, n * 4)
            _rect(queue, abuf, _contiguous(a), box, True)
        else:
            abuf = fbuf         # unused: the kernel reads channel k of fg
        launch(cl.Kernel(prg, "over_box"), box, fbuf, np.int32(fg.shape[2]), np.int32(nf), abuf, np.int32(-1 if k is None else k))
    _rect(queue, obuf, out, u, False)
    queue.finish()
    return out
