"""Outputs as files for the client: an 8-bit sRGB PNG, a JPEG (the page's previews
while a handle moves: a tenth of the PNG's encoding time), or a float EXR written
the way the output's port type writes files (``Session.write_output``)."""
from __future__ import annotations

import io
import os
import tempfile
from typing import Any

import numpy as np

from .errors import ServeError


def image(value: Any, name: str) -> np.ndarray:
    """``value`` when it is an image (float, 2-D or H x W x C), else a 400."""
    if not isinstance(value, np.ndarray) or value.ndim not in (2, 3) or value.dtype.kind != "f":
        raise ServeError(400, f"output {name!r} is a {type(value).__name__}, not an image", field="output")
    return value


def downscale(img: np.ndarray, s: int) -> np.ndarray:
    """Box-filter downscale by an integer factor, in linear light (edges cropped)."""
    if s <= 1:
        return img
    h, w = (img.shape[0] // s) * s, (img.shape[1] // s) * s
    x = img[:h, :w].reshape(h // s, s, w // s, s, *img.shape[2:])
    return x.mean(axis=(1, 3), dtype=np.float32)


def srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1) of linear values in [0, 1], float32."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.0031308, x * 12.92,
                    1.055 * np.power(np.maximum(x, 0.0031308), 1.0 / 2.4) - 0.055).astype(np.float32)


#: values of the float image converted at a time by ``encode_png`` (bounds its temporaries)
BAND_VALUES = 1 << 20


def _to_u8(img: np.ndarray) -> np.ndarray:
    """8-bit sRGB, straight alpha, of linear premultiplied rows (H x W or H x W x C)."""
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim == 3 and img.shape[2] in (2, 4):
        a = np.clip(img[:, :, -1:], 0.0, 1.0)
        colour = np.where(a > 0, img[:, :, :-1] / np.where(a > 0, a, 1.0), 0.0)
        img = np.concatenate([srgb(np.clip(colour, 0.0, 1.0)), a], axis=2)
    else:
        img = srgb(np.clip(img, 0.0, 1.0))
    return (img * 255.0 + 0.5).astype(np.uint8)


def encode_png(value: Any, name: str = "image", scale: int = 1, compress: int = 1) -> bytes:
    """An 8-bit sRGB PNG (straight alpha) of a linear, premultiplied image or mask,
    box-downscaled by ``scale``. Converted in bands of rows, so the float temporaries
    stay near ``BAND_VALUES`` values whatever the image's size."""
    from PIL import Image

    img = image(value, name)
    s = max(1, int(scale))
    h, w = img.shape[0] // s, img.shape[1] // s
    channels = 1 if img.ndim == 2 else img.shape[2]
    u8 = np.empty((h, w) if channels == 1 else (h, w, channels), np.uint8)
    rows = max(1, BAND_VALUES // max(1, img.shape[1] * channels * s))
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        u8[r0:r1] = _to_u8(downscale(img[r0 * s:r1 * s], s))
    mode = "L" if u8.ndim == 2 else {2: "LA", 3: "RGB", 4: "RGBA"}[u8.shape[2]]
    buf = io.BytesIO()
    Image.fromarray(u8, mode).save(buf, format="PNG", compress_level=compress)
    del u8
    return buf.getvalue()


#: linear value -> 8-bit sRGB, for ``encode_jpeg``: indexed by the value quantised to 16 bits
#: (a step of 1.5e-5 linear, finer than an 8-bit sRGB step anywhere: at most one level off
#: where a value falls within that step of a rounding boundary)
_LUT_STEPS = 65535
_SRGB_LUT = None


def _srgb_u8(x: np.ndarray) -> np.ndarray:
    global _SRGB_LUT
    if _SRGB_LUT is None:
        _SRGB_LUT = (srgb(np.arange(_LUT_STEPS + 1, dtype=np.float32) / _LUT_STEPS) * 255.0 + 0.5).astype(np.uint8)
    idx = np.empty(x.shape, np.float32)
    np.clip(x, 0.0, 1.0, out=idx)
    idx *= _LUT_STEPS
    idx += 0.5
    return _SRGB_LUT[idx.astype(np.uint16)]


def encode_jpeg(value: Any, name: str = "image", scale: int = 1, quality: int = 85) -> bytes:
    """A baseline JPEG (8-bit sRGB, 4:2:0) of a linear image, box-downscaled by ``scale``.
    JPEG has no alpha: an image with alpha is shown over black (its premultiplied
    colour), a mask as grey. For previews: quick to encode and to decode."""
    from PIL import Image

    img = downscale(image(value, name), max(1, int(scale)))
    if img.ndim == 3 and img.shape[2] == 1:
        img = img[:, :, 0]
    if img.ndim == 3 and img.shape[2] in (2, 4):
        img = img[:, :, :-1]
    u8 = _srgb_u8(img)
    buf = io.BytesIO()
    Image.fromarray(u8, "L" if u8.ndim == 2 else "RGB").save(buf, format="JPEG", quality=int(quality))
    return buf.getvalue()


def encode_exr(session, graph, value: Any, name: str) -> bytes:
    """The output as an EXR file's bytes, written by its port type (linear, premultiplied)."""
    image(value, name)
    with tempfile.TemporaryDirectory(prefix="pixgraph-exr-") as d:
        try:
            path = session.write_output(graph, name, value, os.path.join(d, "out.exr"))
        except ValueError as e:
            raise ServeError(400, str(e), field="output") from None
        with open(path, "rb") as f:
            return f.read()
