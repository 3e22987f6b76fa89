"""PNG encoding for big images: the "Up" row filter and a fast deflate, a band of rows at a time.

A general-purpose PNG writer (libpng through OpenImageIO, Pillow) picks a filter
for every row by trying all five and compresses with zlib; at photo size that
costs 1-1.2 CPU seconds for 20 megapixels at zlib level 1 (about 4.6 s at the
default level 6). Photos and renders compress as well or better with one fixed
filter, *Up* (each byte minus the byte above it; PNG filter type 2), which numpy
computes in one subtraction, and with ISA-L's deflate (``isal``; level 1 is as
small as zlib's level 6 on such images, about 30x faster). Measured by
``python benchmarks/batch_bench.py --png`` (table in docs/batch.md).

The file is a plain PNG (ISO/IEC 15948): signature, ``IHDR``, for colour images
``sRGB`` + ``gAMA`` + ``cHRM`` (the sRGB chunk and its fallback values, as the
PNG specification recommends), one ``IDAT`` per band of rows, ``IEND``. 8- or
16-bit samples (16-bit big-endian), grey, grey + alpha, RGB or RGBA.

``level``: ``None`` (the default) is the fast setting (ISA-L level 1 when the
``isal`` package is installed, else zlib level 1); ``0``..``9`` are zlib's levels
(``9``: the smallest file, ~15 % smaller and ~100x slower than the default).
"""
from __future__ import annotations

import struct
import zlib

import numpy as np

try:  # ISA-L's deflate (a base dependency; wheels for Linux, macOS and Windows)
    from isal import isal_zlib as _isal
except ImportError:  # pragma: no cover - a platform without the wheel: zlib, same files, slower
    _isal = None

#: PNG colour type by channel count: grey, grey + alpha, RGB, RGBA
COLOUR_TYPES = {1: 0, 2: 4, 3: 2, 4: 6}
SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: sRGB chunk (rendering intent 0, perceptual), gAMA 1/2.2 and cHRM of the sRGB
#: primaries and D65 white point, in units of 1e-5 (PNG specification, 11.3.3.5)
_SRGB = b"\x00"
_GAMA = struct.pack(">I", 45455)
_CHRM = struct.pack(">8I", 31270, 32900, 64000, 33000, 30000, 60000, 15000, 6000)
#: rows per band: the filtered copy held at once (about 4 MB for a 5120-px RGB row band of 256)
BAND_BYTES = 4 << 20


def deflate_backend(level: int | None = None) -> str:
    """The deflate library a PNG of compression ``level`` is written with: ``"isal"``
    (the fast default when installed) or ``"zlib"``."""
    return "isal" if level is None and _isal is not None else "zlib"


def _compressor(level: int | None):
    if level is None:
        return _isal.compressobj(1) if _isal is not None else zlib.compressobj(1)
    if not isinstance(level, int) or isinstance(level, bool) or not 0 <= level <= 9:
        raise ValueError(f"PNG compression level must be an integer 0..9 or None (fast), got {level!r}")
    return zlib.compressobj(level)


def _chunk(f, kind: bytes, data: bytes) -> None:
    f.write(struct.pack(">I", len(data)))
    f.write(kind)
    f.write(data)
    f.write(struct.pack(">I", zlib.crc32(data, zlib.crc32(kind)) & 0xFFFFFFFF))


def up_filtered(rows: np.ndarray, above: np.ndarray | None) -> np.ndarray:
    """PNG scanlines of ``rows`` (uint8, (n, bytes per row)) with filter type 2 (Up):
    a leading byte 2, then each byte minus the byte above it modulo 256 (``above``:
    the last row of the previous band, None for the image's first row, which has
    zeros above it)."""
    n, width = rows.shape
    out = np.empty((n, width + 1), np.uint8)
    out[:, 0] = 2
    if above is None:
        out[0, 1:] = rows[0]
    else:
        np.subtract(rows[0], above, out=out[0, 1:])
    if n > 1:
        np.subtract(rows[1:], rows[:-1], out=out[1:, 1:])
    return out


def write_png(f, pixels: np.ndarray, srgb: bool = True, level: int | None = None) -> None:
    """Write ``pixels`` (uint8 or uint16, (H, W) or (H, W, C) with C in 1..4: grey,
    grey + alpha, RGB, RGBA; alpha straight) as a PNG to the binary file ``f``.
    ``srgb``: mark the colour as sRGB (sRGB, gAMA, cHRM chunks); False for data
    (mattes, pixel heights: numbers, no colour space). ``level``: see the module."""
    a = np.asarray(pixels)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in COLOUR_TYPES or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"a PNG holds (H, W) or (H, W, C) pixels with C in 1..4, got shape {np.shape(pixels)}")
    if a.dtype == np.uint8:
        depth = 8
    elif a.dtype == np.uint16:
        depth = 16
        a = a.astype(">u2", copy=False)  # PNG samples are big-endian
    else:
        raise ValueError(f"PNG pixels must be uint8 or uint16, got {a.dtype}")
    h, w, c = a.shape
    if h >= 1 << 31 or w >= 1 << 31:
        raise ValueError(f"a PNG is at most 2^31 - 1 pixels wide and high, got {w}x{h}")
    comp = _compressor(level)
    rows = np.ascontiguousarray(a).view(np.uint8).reshape(h, w * c * depth // 8)
    f.write(SIGNATURE)
    _chunk(f, b"IHDR", struct.pack(">IIBBBBB", w, h, depth, COLOUR_TYPES[c], 0, 0, 0))
    if srgb:
        _chunk(f, b"sRGB", _SRGB)
        _chunk(f, b"gAMA", _GAMA)
        _chunk(f, b"cHRM", _CHRM)
    band = max(1, BAND_BYTES // rows.shape[1])
    above = None
    for r0 in range(0, h, band):
        block = rows[r0:r0 + band]
        data = comp.compress(up_filtered(block, above))
        above = block[-1]
        if data:
            _chunk(f, b"IDAT", data)
    _chunk(f, b"IDAT", comp.flush())
    _chunk(f, b"IEND", b"")
