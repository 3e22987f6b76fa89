"""Image file I/O: every image the package reads or writes goes through here.

Inside pixgraph an image is float32 ``(H, W, C)`` (or ``(H, W)``), **linear light,
alpha premultiplied** when ``C`` is 4 (or 2: grey + alpha). Files differ:

- PNG / JPEG / 8- and 16-bit TIFF hold sRGB-encoded colour with *straight*
  (unassociated) alpha;
- OpenEXR holds linear, premultiplied float colour with named channels.

OpenImageIO premultiplies RGBA PNGs (and TIFFs with unassociated alpha) on read
unless told not to; we always pass ``oiio:UnassociatedAlpha = 1`` so that we get
the file's numbers untouched, and do the conversion here, explicitly:
decode sRGB on straight colour, then premultiply (encoding sRGB of a premultiplied
colour would darken every soft edge).
"""
from __future__ import annotations

import os
import pathlib

import numpy as np

from pixgraph.node import InputError
from pixgraph.options import env_int

from .bands import for_bands
from .png import write_png

#: file extensions whose colour is linear float (everything else is sRGB-encoded)
LINEAR_EXTENSIONS = (".exr", ".hdr")
#: largest image read, in pixels (width x height x depth), checked from the file's
#: header before any pixel is decoded; ``PIXGRAPH_MAX_PIXELS`` overrides it
DEFAULT_MAX_PIXELS = 64 * 1024 * 1024


class ImageFileError(InputError, OSError):
    """An image file that cannot be read, is larger than allowed, or cannot be
    written as asked (extension, bit depth, shape): bad input (exit 2). Also an
    ``OSError`` and a ``ValueError`` for callers that catch those."""


def max_pixels() -> int:
    """The pixel limit for image reads (``PIXGRAPH_MAX_PIXELS``, default 64 Mpx)."""
    try:
        return env_int("PIXGRAPH_MAX_PIXELS", DEFAULT_MAX_PIXELS)
    except ValueError as e:
        raise ImageFileError(str(e)) from None


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB decode of values in [0, 1] to linear light (float32)."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.04045, x / 12.92, ((np.maximum(x, 0.04045) + 0.055) / 1.055) ** 2.4).astype(np.float32)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """sRGB encode of linear light to display values (float32; [0, 1] in, [0, 1] out)."""
    x = np.asarray(x, dtype=np.float32)
    return np.where(x <= 0.0031308, x * 12.92,
                    1.055 * np.power(np.maximum(x, 0.0031308), 1.0 / 2.4) - 0.055).astype(np.float32)


def _oiio():
    import OpenImageIO as oiio

    return oiio


def _is_linear_file(path: str | os.PathLike) -> bool:
    return pathlib.Path(path).suffix.lower() in LINEAR_EXTENSIONS


def _alpha_channel(nchannels: int) -> int | None:
    """Index of the alpha channel for the layouts we accept: grey+A (2) or RGBA (4)."""
    return {2: 1, 4: 3}.get(nchannels)


def read_image(path: str | os.PathLike, colorspace: str = "auto",
               alpha: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Read an image file into pixgraph's convention.

    colorspace: ``"srgb"``, ``"linear"`` or ``"auto"`` (EXR/HDR linear, others sRGB):
        how the file's colour is encoded.
    alpha: ``"straight"``, ``"premultiplied"`` or ``"auto"`` (EXR/HDR premultiplied,
        others straight): what the *file* holds.

    Returns ``(image, alpha)``: ``image`` float32 ``(H, W, C)``, linear light,
    premultiplied (C as in the file: 1, 2, 3 or 4); ``alpha`` float32 ``(H, W)``
    in [0, 1], all ones when the file has no alpha channel.
    """
    if colorspace not in ("srgb", "linear", "auto"):
        raise ValueError(f"colorspace must be srgb, linear or auto, got {colorspace!r}")
    if alpha not in ("straight", "premultiplied", "auto"):
        raise ValueError(f"alpha must be straight, premultiplied or auto, got {alpha!r}")
    oiio = _oiio()
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    data, _ = _read_float(oiio, path, config, keep_uint8=True)
    if colorspace == "auto":
        colorspace = "linear" if _is_linear_file(path) else "srgb"
    if alpha == "auto":
        alpha = "premultiplied" if _is_linear_file(path) else "straight"
    if data.dtype == np.uint8:
        if colorspace == "srgb" and (alpha == "straight" or _alpha_channel(data.shape[2]) is None):
            return _decode_srgb8(data)
        data = data.astype(np.float32) * np.float32(1.0 / 255.0)
    return to_internal(data, colorspace, alpha)


#: sRGB decode of every 8-bit code: ``srgb_to_linear(k / 255)`` (the same float32 numbers)
_SRGB8_TO_LINEAR = None


def _decode_srgb8(data: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``to_internal(data / 255, "srgb", "straight")`` of an 8-bit file, by table:
    the same numbers (every code's decode is looked up, not recomputed), a few
    times faster at photo size."""
    global _SRGB8_TO_LINEAR
    if _SRGB8_TO_LINEAR is None:
        _SRGB8_TO_LINEAR = srgb_to_linear(np.arange(256, dtype=np.float32) / np.float32(255.0))
    H, W, C = data.shape
    ai = _alpha_channel(C)
    image = np.empty((H, W, C), np.float32)
    table = _SRGB8_TO_LINEAR
    if ai is None:
        # bands of rows on the machine's cores (ops/bands.py); "clip" never clips (256
        # entries for uint8 codes) but spares numpy a buffered copy of ``out``
        for_bands(lambda r0, r1: np.take(table, data[r0:r1], out=image[r0:r1], mode="clip"), 0, H, 128)
        # a photo's coverage is all ones: a read-only broadcast of one value, not H*W floats
        return image, np.broadcast_to(np.float32(1.0), (H, W))
    a = np.empty((H, W), np.float32)

    def band(r0, r1):
        np.multiply(data[r0:r1, :, ai], np.float32(1.0 / 255.0), out=a[r0:r1])
        for c in range(C):
            if c == ai:
                image[r0:r1, :, c] = a[r0:r1]
            else:
                image[r0:r1, :, c] = table[data[r0:r1, :, c]] * a[r0:r1]
    for_bands(band, 0, H, 128)
    return image, a


def to_internal(data: np.ndarray, colorspace: str, alpha: str) -> tuple[np.ndarray, np.ndarray]:
    """Pixels as a file or host holds them -> pixgraph's ``(image, alpha)``.

    data: float (H, W, C), C in 1..4 (alpha last when C is 2 or 4), values as stored;
    colorspace ``"srgb"`` or ``"linear"``; alpha ``"straight"`` or ``"premultiplied"``.
    Returns ``image`` float32 (H, W, C) linear premultiplied and ``alpha`` float32
    (H, W) in [0, 1] (ones when there is no alpha channel).
    """
    ai = _alpha_channel(data.shape[2])
    if ai is None:
        a = np.ones(data.shape[:2], np.float32)
        colour = data
    else:
        a = np.clip(data[:, :, ai], 0.0, 1.0)
        colour = np.delete(data, ai, axis=2)
    if colorspace == "srgb":
        if alpha == "premultiplied" and ai is not None:
            # decode needs straight colour: unpremultiply, decode, premultiply again
            colour = _unpremultiply(colour, a)
        colour = srgb_to_linear(np.clip(colour, 0.0, 1.0))
        if ai is not None:
            colour = colour * a[:, :, None]
    elif alpha == "straight" and ai is not None:
        colour = colour * a[:, :, None]
    if ai is None:
        image = colour
    else:
        image = np.concatenate([colour, a[:, :, None]], axis=2)
    return np.ascontiguousarray(image, dtype=np.float32), a.astype(np.float32)


def host_pixels(array, channels: tuple[int, ...], what: str) -> np.ndarray:
    """A host's numpy array as float32 values: float dtypes as they are, unsigned
    integers normalised (``v / 255``, ``v / 65535``); (H, W) becomes (H, W, 1).

    Raises ``ValueError`` (one line) for another type, shape or channel count.
    NaN / infinite values are passed on: the nodes that use them refuse them where
    they matter (inside the cutout), naming the input and the pixel.
    """
    if not isinstance(array, np.ndarray):
        raise ValueError(f"{what} must be a numpy array, got {type(array).__name__}")
    a = array
    if a.dtype.kind == "u":
        a = a.astype(np.float32) / np.float32(np.iinfo(a.dtype).max)
    elif a.dtype.kind != "f":
        raise ValueError(f"{what} must be float or unsigned integer, got dtype {a.dtype}")
    a = np.asarray(a, dtype=np.float32)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[2] not in channels or a.shape[0] < 1 or a.shape[1] < 1:
        want = " or ".join(f"(H, W, {c})" for c in channels)
        raise ValueError(f"{what} must have shape {want}, got {array.shape}")
    return np.ascontiguousarray(a)


def read_header(path: str | os.PathLike) -> tuple[int, int, int]:
    """``(height, width, channels)`` of an image file from its header (no pixels
    read), or of a ``.npy`` array (its header; 2-D arrays have 1 channel).
    Raises ``OSError`` when the file cannot be opened as an image."""
    p = pathlib.Path(path)
    if p.suffix.lower() == ".npy":
        a = np.load(p, mmap_mode="r", allow_pickle=False)
        if a.ndim not in (2, 3):
            raise OSError(f"{p}: expected a 2-D or 3-D array, got shape {a.shape}")
        return int(a.shape[0]), int(a.shape[1]), int(a.shape[2]) if a.ndim == 3 else 1
    inp = _oiio().ImageInput.open(str(p))
    if inp is None:
        raise OSError(f"cannot read image {p}: {_oiio().geterror()}".splitlines()[0])
    try:
        spec = inp.spec()
        return int(spec.height), int(spec.width), int(spec.nchannels)
    finally:
        inp.close()


def read_raw(path: str | os.PathLike) -> tuple[np.ndarray, list[str]]:
    """A file's stored values as float32 (H, W, C) and its channel names: integers
    normalised to [0, 1], never colour-decoded or premultiplied (for data: masks,
    pixel heights, darkness)."""
    oiio = _oiio()
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    return _read_float(oiio, path, config)


def read_mask(path: str | os.PathLike) -> np.ndarray:
    """A mask (matte) file as float32 (H, W) in [0, 1].

    ``.npy`` (the PixHt-Lab authors' format): (H, W) or (H, W, C) (first channel);
    bool, unsigned integers (divided by their maximum), or floats (divided by 255
    when the largest value is over 1: a 0..255 matte). Images: the alpha channel
    when there is one, else the first channel, as stored (a matte is data: never
    sRGB-decoded). Raises ``ValueError`` for NaN values or another shape.
    """
    p = pathlib.Path(path)
    if p.suffix.lower() == ".npy":
        a = np.load(p, allow_pickle=False)
        if a.dtype == bool:
            a = a.astype(np.float32)
        elif a.dtype.kind == "u":
            a = a.astype(np.float32) / np.float32(np.iinfo(a.dtype).max)
        elif a.dtype.kind == "f":
            a = a.astype(np.float32)
            if np.isfinite(a).all() and a.size and a.max() > 1.0:
                a = a / np.float32(255.0)
        else:
            raise ValueError(f"{p}: a mask must be bool, unsigned or float, got dtype {a.dtype}")
        if a.ndim == 3:
            a = a[:, :, 0]
    else:
        data, names = read_raw(p)
        ai = _alpha_channel(data.shape[2])
        a = data[:, :, ai if ai is not None else 0]
    if a.ndim != 2:
        raise ValueError(f"{p}: expected a 2-D mask, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{p}: mask has NaN or infinite values")
    return np.ascontiguousarray(np.clip(a, 0.0, 1.0), dtype=np.float32)


def _unpremultiply(colour: np.ndarray, a: np.ndarray) -> np.ndarray:
    safe = np.where(a > 0.0, a, 1.0)[:, :, None]
    return np.where(a[:, :, None] > 0.0, colour / safe, 0.0).astype(np.float32)


def _as_hwc(array: np.ndarray) -> np.ndarray:
    array = np.asarray(array, dtype=np.float32)
    if array.ndim == 2:
        array = array[:, :, None]
    if array.ndim != 3 or not 1 <= array.shape[2] <= 4:
        raise ImageFileError(f"expected an (H, W) or (H, W, C<=4) image, got shape {array.shape}")
    return array


def write_image(path: str | os.PathLike, array: np.ndarray, bit_depth: int | None = None,
                compression: int | None = None) -> str:
    """Write a linear, premultiplied float32 image to ``path``; the extension picks the format.

    - ``.png``, ``.tif``/``.tiff``: sRGB-encoded, straight alpha, ``bit_depth`` 8
      (default) or 16.
    - ``.jpg``/``.jpeg``: sRGB-encoded 8 bit; JPEG has no alpha, so colour is
      written over black (the premultiplied colour) and alpha is dropped.
    - ``.exr``: linear, premultiplied, ``bit_depth`` 16 (half) or 32 (float,
      default), channels ``R,G,B[,A]`` (``Y`` / ``Y,A`` for grey).
    - ``.npy``: the float32 array as it is (linear, premultiplied).

    PNGs are encoded by ``png.write_png`` (one row filter and ISA-L's deflate: at
    20 megapixels about 8x less CPU than libpng's zlib level 1, and as small as
    its default level 6); ``compression`` 0..9 asks for zlib at that level instead
    (9: the smallest file, much slower); ``None`` is the fast default. Other
    formats take no ``compression``.

    Data maps (mattes, darkness, pixel heights) go through ``write_data`` instead.

    The file is written to a temporary name next to it and renamed, so a reader
    never sees a half-written image. Returns the path written, as a string.
    """
    target, path = path, str(path)
    ext = pathlib.Path(path).suffix.lower()
    if ext == ".npy":  # the array itself: float32 linear premultiplied, exact
        a = np.ascontiguousarray(array, dtype=np.float32)
        _write_via_temp(target, ".npy", lambda f, tmp: np.save(f, a))
        return path
    if compression is not None and ext != ".png":
        raise ImageFileError(f"compression applies to PNG files only, not {ext} ({path})")
    oiio = _oiio()
    img = _as_hwc(array)
    h, w, c = img.shape
    ai = _alpha_channel(c)
    names = {1: ["Y"], 2: ["Y", "A"], 3: ["R", "G", "B"], 4: ["R", "G", "B", "A"]}[c]
    if ext == ".exr":
        bit_depth = 32 if bit_depth is None else bit_depth
        if bit_depth not in (16, 32):
            raise ImageFileError(f"EXR bit_depth must be 16 or 32, got {bit_depth}")
        fmt = oiio.HALF if bit_depth == 16 else oiio.FLOAT
        spec = oiio.ImageSpec(w, h, c, fmt)
        spec.channelnames = tuple(names)
        if ai is not None:
            spec.alpha_channel = ai
        pixels = img
    elif ext in (".png", ".tif", ".tiff", ".jpg", ".jpeg"):
        jpeg = ext in (".jpg", ".jpeg")
        bit_depth = 8 if bit_depth is None else bit_depth
        if bit_depth not in (8, 16) or (jpeg and bit_depth != 8):
            raise ImageFileError(f"{ext} bit_depth must be 8{'' if jpeg else ' or 16'}, got {bit_depth}")
        if jpeg and ai is not None:
            img = np.delete(img, ai, axis=2)
            c, ai = img.shape[2], None
            names = names[:c] if c == 3 else ["Y"]
        if bit_depth == 8:   # straight to the file's 8-bit codes, by table, a band of rows at a time
            pixels = _encode_srgb8(img, ai)
        elif ai is not None:
            a = np.clip(img[:, :, ai], 0.0, 1.0)
            colour = linear_to_srgb(np.clip(_unpremultiply(np.delete(img, ai, axis=2), a), 0.0, 1.0))
            pixels = np.insert(colour, ai, a, axis=2)
        else:
            pixels = linear_to_srgb(np.clip(img, 0.0, 1.0))
        if ext == ".png":
            codes = pixels if bit_depth == 8 else _to_uint16(pixels)
            _write_via_temp(target, ".png", lambda f, via: write_png(f, codes, srgb=True, level=compression))
            return path
        fmt = oiio.UINT8 if bit_depth == 8 else oiio.UINT16
        spec = oiio.ImageSpec(w, h, c, fmt)
        spec.channelnames = tuple(names)
        if ai is not None:
            spec.alpha_channel = ai
            # our pixels are already straight: stop OIIO from un-associating again
            spec.attribute("oiio:UnassociatedAlpha", 1)
        spec.attribute("oiio:ColorSpace", "sRGB")
    else:
        raise ImageFileError(f"unsupported image extension {ext!r} for {path} (png, tif, jpg, exr)")
    _write_atomic(oiio, target, spec, pixels if pixels.dtype == np.uint8 else
                  np.ascontiguousarray(pixels, dtype=np.float32))
    return path


def _to_uint16(values: np.ndarray) -> np.ndarray:
    """Values in [0, 1] (clipped) -> 16-bit codes ``round(65535 v)``."""
    return np.round(np.clip(values, 0.0, 1.0) * np.float32(65535.0)).astype(np.uint16)


#: linear value i / 65535 -> 8-bit sRGB code (``round(255 linear_to_srgb)``)
_LINEAR16_TO_SRGB8 = None


def _encode_srgb8(img: np.ndarray, ai: int | None, band: int = 64) -> np.ndarray:
    """Linear premultiplied float (H, W, C) -> 8-bit sRGB codes with straight alpha
    (uint8, H, W, C), by a table of 65536 linear levels: within one code of
    ``round(255 * linear_to_srgb(x))`` (off by one only where x lies within 1/131070
    of a code's boundary), a band of rows at a time (no full-size float copies)."""
    global _LINEAR16_TO_SRGB8
    if _LINEAR16_TO_SRGB8 is None:
        levels = np.arange(65536, dtype=np.float32) / np.float32(65535.0)
        _LINEAR16_TO_SRGB8 = np.round(linear_to_srgb(levels) * 255.0).astype(np.uint8)
    lut = _LINEAR16_TO_SRGB8
    H, W, C = img.shape
    out = np.empty((H, W, C), np.uint8)
    if ai is None:  # all channels through the table at once, a band's temporaries per band

        def opaque(r0, r1):
            t = np.clip(img[r0:r1], 0.0, 1.0)
            np.multiply(t, np.float32(65535.0), out=t)
            np.add(t, np.float32(0.5), out=t)
            ix = np.empty(t.shape, np.uint16)
            np.copyto(ix, t, casting="unsafe")  # truncation of x + 0.5: rounding
            np.take(lut, ix, out=out[r0:r1], mode="clip")
        for_bands(opaque, 0, H, band)
        return out

    def straight(r0, r1):
        blk = img[r0:r1]
        a = np.clip(blk[:, :, ai], 0.0, 1.0)
        colour = np.clip(_unpremultiply(np.delete(blk, ai, axis=2), a), 0.0, 1.0)
        out[r0:r1, :, ai] = np.round(a * 255.0).astype(np.uint8)
        idx = (colour * np.float32(65535.0) + np.float32(0.5)).astype(np.uint16)
        for k, c in enumerate(c for c in range(C) if c != ai):
            out[r0:r1, :, c] = lut[idx[:, :, k]]
    for_bands(straight, 0, H, band)
    return out


#: extensions ``write_data`` can write
DATA_EXTENSIONS = (".npy", ".exr", ".tif", ".tiff", ".png")


def write_data(path: str | os.PathLike, array: np.ndarray, bit_depth: int | None = None,
               white: float = 1.0, compression: int | None = None) -> str:
    """Write a data map (a matte, a shadow darkness, a pixel height: float (H, W)) so
    that reading it back gives the same numbers: never sRGB-encoded, never clipped.

    - ``.npy``: float32, exact (read back with ``np.load``, LoadMask, LoadPixelHeight).
    - ``.exr``: one float channel ``Y``, exact (``bit_depth`` 16: half floats).
    - ``.tif``/``.tiff``: float32 (default, exact), or ``bit_depth`` 8/16 as below.
    - ``.png``: 16-bit (default) or 8-bit integers holding ``value / white``, linear
      (no gamma): exact to 1 / 65535 (1 / 255) of ``white``. Values outside
      ``[0, white]`` are a ``ValueError`` naming the range (use .npy or .exr), since
      an integer file cannot hold them.
    NaN or infinite values are a ``ValueError``. Written atomically (temp + rename).
    ``compression``: PNG only, as for ``write_image``.
    """
    target, path = path, str(path)
    ext = pathlib.Path(path).suffix.lower()
    if compression is not None and ext != ".png":
        raise ValueError(f"compression applies to PNG files only, not {ext} ({path})")
    a = np.asarray(array, dtype=np.float32)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    if a.ndim != 2:
        raise ValueError(f"a data map is (H, W), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{path}: the map has NaN or infinite values")
    if ext == ".npy":
        _write_via_temp(target, ".npy", lambda f, tmp: np.save(f, np.ascontiguousarray(a)))
        return path
    oiio = _oiio()
    integer = ext == ".png" or (ext in (".tif", ".tiff") and bit_depth in (8, 16))
    if integer:
        bit_depth = 16 if bit_depth is None else bit_depth
        if bit_depth not in (8, 16):
            raise ValueError(f"{ext} data bit_depth must be 8 or 16, got {bit_depth}")
        if not white > 0:
            raise ValueError(f"white must be positive, got {white}")
        lo, hi = float(a.min()), float(a.max())
        if lo < 0.0 or hi > white * (1 + 1e-6):
            raise ValueError(f"values {lo:g}..{hi:g} do not fit a {bit_depth}-bit {ext} holding 0..{white:g} "
                             f"(write .npy or .exr, or set white)")
        pixels = np.clip(a / np.float32(white), 0.0, 1.0)
        if ext == ".png":  # numbers, no colour space chunks
            codes = _to_uint16(pixels) if bit_depth == 16 else np.round(pixels * np.float32(255.0)).astype(np.uint8)
            _write_via_temp(target, ".png", lambda f, via: write_png(f, codes, srgb=False, level=compression))
            return path
        spec = oiio.ImageSpec(a.shape[1], a.shape[0], 1, oiio.UINT8 if bit_depth == 8 else oiio.UINT16)
    elif ext in (".exr", ".tif", ".tiff"):
        bit_depth = 32 if bit_depth is None else bit_depth
        if bit_depth not in (16, 32) or (bit_depth == 16 and ext != ".exr"):
            raise ValueError(f"{ext} float bit_depth must be 32{' or 16' if ext == '.exr' else ''}, got {bit_depth}")
        spec = oiio.ImageSpec(a.shape[1], a.shape[0], 1, oiio.HALF if bit_depth == 16 else oiio.FLOAT)
        pixels = a
    else:
        raise ValueError(f"cannot write a data map to {ext!r} ({path}): use .npy, .exr, .tif or .png")
    spec.channelnames = ("Y",)
    _write_atomic(oiio, target, spec, np.ascontiguousarray(pixels[:, :, None], dtype=np.float32))
    return path


def read_data(path: str | os.PathLike, white: float = 1.0) -> np.ndarray:
    """A data map written by ``write_data`` (or any single-channel file) as float32
    (H, W): ``.npy`` as stored, float files as stored, integer files ``v / max * white``."""
    p = pathlib.Path(path)
    if p.suffix.lower() == ".npy":
        return np.asarray(np.load(p, allow_pickle=False), dtype=np.float32)
    data, _ = read_raw(p)
    inp = _oiio().ImageInput.open(str(p))
    fmt = str(inp.spec().format)
    inp.close()
    scale = white if fmt.startswith("uint") else 1.0
    return (data[:, :, 0] * np.float32(scale)).astype(np.float32)


def _write_atomic(oiio, path, spec, pixels: np.ndarray) -> None:
    # no time stamp (OpenImageIO writes the clock's time into EXR and TIFF headers): the
    # same pixels give the same bytes, so a file's digest says whether its image changed
    spec.attribute("DateTime", "")

    def fill(f, via):
        out = oiio.ImageOutput.create("x" + os.path.splitext(str(path))[1])  # the format, by extension
        if out is None:
            raise OSError(f"cannot write image {path}: {oiio.geterror()}")
        try:
            if not out.open(via, spec):
                raise OSError(f"cannot write image {path}: {out.geterror()}")
            if not out.write_image(pixels):
                raise OSError(f"cannot write image {path}: {out.geterror()}")
        finally:
            out.close()

    _write_via_temp(path, os.path.splitext(str(path))[1], fill)


def _write_via_temp(path, suffix: str, fill) -> None:
    """Write the file ``path`` through a temporary next to it, renamed into place (a
    reader never sees half a file), without following any symlink: the folder is
    opened by ``pixgraph.paths.open_write_folder`` (for a node's ``WritePath``, the
    folder the path policy checked; missing folders are created), the temporary is
    created there with ``O_EXCL | O_NOFOLLOW`` under a random name, and
    ``fill(file, via)`` writes it: to the open file, or (OpenImageIO) by the path
    ``via``, which is ``/proc/self/fd/N`` of that very file, so the bytes go to the
    file created whatever happens to names in the folder meanwhile. The rename is
    refused if the temporary's name no longer holds that file. A folder on the way
    that became a symlink is an ``ImageFileError`` (bad input): nothing is written."""
    import stat
    import uuid

    from pixgraph.paths import PathError, open_write_folder, temp_stem

    try:
        folder, name = open_write_folder(path)
    except PathError as e:
        raise ImageFileError(e.message) from None
    stem = temp_stem(os.path.splitext(name)[0], len(suffix.encode("utf-8", "surrogateescape")))
    tmp = f".{stem}.tmp-{os.getpid()}-{uuid.uuid4().hex[:8]}{suffix}"
    created = False
    try:
        fd = folder.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        created = True
        with os.fdopen(fd, "wb") as f:
            inode = os.fstat(f.fileno()).st_ino
            via = f"/proc/self/fd/{f.fileno()}"
            if not os.path.exists(via):  # no /proc (not Linux): the temporary's path in the checked folder
                via = os.path.join(folder.path, tmp)
            fill(f, via)
        st = folder.lstat(tmp)
        if not stat.S_ISREG(st.st_mode) or (st.st_ino and st.st_ino != inode):
            raise ImageFileError(f"cannot write {path}: its temporary file was replaced while it was written")
        folder.replace(tmp, name)
        created = False
    finally:
        if created:
            try:
                folder.unlink(tmp)
            except OSError:
                pass
        folder.close()


def write_exr_channels(path: str | os.PathLike, channels: dict[str, np.ndarray], bit_depth: int = 32) -> str:
    """Write named float ``(H, W)`` channels (e.g. SSN++ buffers) to one EXR, in dict order."""
    oiio = _oiio()
    if not channels:
        raise ValueError("write_exr_channels needs at least one channel")
    arrays = [np.asarray(v, dtype=np.float32) for v in channels.values()]
    shape = arrays[0].shape
    for name, arr in zip(channels, arrays):
        if arr.ndim != 2 or arr.shape != shape:
            raise ValueError(f"channel {name!r} has shape {arr.shape}, expected {shape} (H, W)")
    if bit_depth not in (16, 32):
        raise ImageFileError(f"EXR bit_depth must be 16 or 32, got {bit_depth}")
    spec = oiio.ImageSpec(shape[1], shape[0], len(arrays), oiio.HALF if bit_depth == 16 else oiio.FLOAT)
    spec.channelnames = tuple(channels)
    _write_atomic(oiio, path, spec, np.ascontiguousarray(np.stack(arrays, axis=2)))
    return str(path)


def read_exr_channels(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Every channel of an EXR (or any image) as ``{name: float32 (H, W)}``, in file order."""
    data, names = _read_float(_oiio(), path)
    return {n: np.ascontiguousarray(data[:, :, i]) for i, n in enumerate(names)}


def _read_float(oiio, path, config=None, keep_uint8: bool = False) -> tuple[np.ndarray, list[str]]:
    """All pixels of an image file as float32 (H, W, C), and its channel names;
    with ``keep_uint8`` an 8-bit file's pixels as stored (uint8: 4x less to convert)."""
    inp = oiio.ImageInput.open(str(path), config) if config is not None else oiio.ImageInput.open(str(path))
    if inp is None:
        raise ImageFileError(f"cannot read image {path}: {oiio.geterror()}"[:300])
    try:
        spec = inp.spec()
        pixels = max(spec.width, 0) * max(spec.height, 0) * max(spec.depth, 1)
        limit = max_pixels()
        if pixels > limit or spec.nchannels > 64:
            raise ImageFileError(f"image {path} is {spec.width}x{spec.height}x{spec.depth} with {spec.nchannels} "
                                 f"channels: more than the limit of {limit} pixels (PIXGRAPH_MAX_PIXELS)")
        if pixels == 0 or spec.nchannels < 1:
            raise ImageFileError(f"image {path} has no pixels ({spec.width}x{spec.height}, {spec.nchannels} channels)")
        names = list(spec.channelnames)
        eight = keep_uint8 and str(spec.format) == "uint8" and not any(
            str(f) != "uint8" for f in (spec.channelformats or ()))
        data = inp.read_image("uint8" if eight else "float")
        if data is None:
            raise ImageFileError(f"cannot read image {path}: {inp.geterror()}"[:300])
    finally:
        inp.close()
    data = np.asarray(data) if eight else np.asarray(data, dtype=np.float32)
    if data.ndim == 2:
        data = data[:, :, None]
    return np.ascontiguousarray(data), names
