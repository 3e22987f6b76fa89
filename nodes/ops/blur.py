"""Gaussian blur: the numpy reference and the OpenCL version (``blur.cl``).

Images are float32 ``(H, W)`` or ``(H, W, C)``; ``sigma`` is the standard
deviation in pixels. The kernel has ``2 * ceil(3 sigma) + 1`` taps, normalised to
sum 1 (as kornia's ``get_gaussian_kernel1d`` for that size), and borders extend
the edge pixel. ``sigma == 0`` returns the image unchanged.
"""
from __future__ import annotations

import math

import numpy as np

from pixgraph.device import load_kernel_source


def gaussian_kernel1d(sigma: float) -> np.ndarray:
    """Normalised 1D Gaussian weights, float32, length ``2 * ceil(3 sigma) + 1``."""
    if sigma < 0:
        raise ValueError(f"sigma must be >= 0 pixels, got {sigma}")
    radius = max(1, math.ceil(3.0 * sigma))
    x = np.arange(-radius, radius + 1, dtype=np.float64)
    w = np.exp(-(x * x) / (2.0 * sigma * sigma))
    return (w / w.sum()).astype(np.float32)


def gaussian_blur_reference(image: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur in numpy (float64 accumulation), edge-clamped borders."""
    img = np.asarray(image, dtype=np.float32)
    if sigma == 0:
        return img.copy()
    w = gaussian_kernel1d(sigma).astype(np.float64)
    r = len(w) // 2
    out = img.astype(np.float64)
    for axis in (1, 0):  # horizontal then vertical, as the OpenCL passes
        pad = [(0, 0)] * out.ndim
        pad[axis] = (r, r)
        padded = np.pad(out, pad, mode="edge")
        n = out.shape[axis]
        acc = np.zeros_like(out)
        for k in range(len(w)):
            acc += w[k] * np.take(padded, np.arange(k, k + n), axis=axis)
        out = acc
    return out.astype(np.float32)


def gaussian_blur(device, image: np.ndarray, sigma: float) -> np.ndarray:
    """Separable Gaussian blur on an OpenCL ``pixgraph.device.Device``; same shape out."""
    import pyopencl as cl

    img = np.ascontiguousarray(image, dtype=np.float32)
    if sigma == 0:
        return img.copy()
    h, w = img.shape[:2]
    channels = 1 if img.ndim == 2 else img.shape[2]
    weights = gaussian_kernel1d(sigma)
    radius = len(weights) // 2
    prg = device.program(load_kernel_source(__file__, "blur.cl"))
    ctx, queue = device.context, device.queue
    mf = cl.mem_flags
    src = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=img)
    tmp = cl.Buffer(ctx, mf.READ_WRITE, img.nbytes)
    dst = cl.Buffer(ctx, mf.READ_WRITE, img.nbytes)
    wbuf = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=weights)
    knl = cl.Kernel(prg, "gaussian_pass")
    dims = np.int32(radius), np.int32(w), np.int32(h), np.int32(channels)
    knl(queue, (w, h), None, src, tmp, wbuf, *dims, np.int32(1))
    knl(queue, (w, h), None, tmp, dst, wbuf, *dims, np.int32(0))
    out = np.empty_like(img)
    cl.enqueue_copy(queue, out, dst)
    return out
