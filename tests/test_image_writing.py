"""PNG writing (nodes/ops/png.py, through imageio.write_image / write_data / SaveImage):
the files decode, with two independent decoders (OpenImageIO's libpng and Pillow), to
exactly the codes given, whatever the depth, channels, band size or deflate library;
the chunks are well formed; colour files say sRGB, data files do not."""
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from pixgraph_nodes.ops import imageio as I
from pixgraph_nodes.ops import png


def _chunks(path):
    """[(type, data)] of a PNG, checking its signature and every CRC."""
    b = open(path, "rb").read()
    assert b[:8] == png.SIGNATURE
    out, i = [], 8
    while i < len(b):
        n, = struct.unpack(">I", b[i:i + 4])
        kind, data = b[i + 4:i + 8], b[i + 8:i + 8 + n]
        crc, = struct.unpack(">I", b[i + 8 + n:i + 12 + n])
        assert crc == zlib.crc32(kind + data) & 0xFFFFFFFF, f"bad CRC in {kind}"
        out.append((kind, data))
        i += 12 + n
    assert i == len(b)
    return out


def _oiio_codes(path):
    oiio = I._oiio()
    config = oiio.ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)
    inp = oiio.ImageInput.open(str(path), config)
    try:
        fmt = str(inp.spec().format)
        data = inp.read_image(fmt)
    finally:
        inp.close()
    data = np.asarray(data)
    return data if data.ndim == 3 else data[:, :, None]


def _pillow_codes(path):
    im = Image.open(path)
    a = np.asarray(im)
    if im.mode in ("I;16", "I;16B", "I"):
        a = a.astype(np.uint16)
    return a if a.ndim == 3 else a[:, :, None]


@pytest.mark.parametrize("channels", [1, 2, 3, 4])
@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
@pytest.mark.parametrize("band_bytes", [1, 200, 4 << 20])  # one row per band, a few rows, one band
def test_png_decodes_to_the_codes_written(tmp_path, monkeypatch, channels, dtype, band_bytes):
    monkeypatch.setattr(png, "BAND_BYTES", band_bytes)
    rng = np.random.default_rng(channels * 10 + np.dtype(dtype).itemsize)
    hi = np.iinfo(dtype).max
    # odd sizes; a smooth part (where Up matters) and a noisy part with extreme codes
    codes = rng.integers(0, hi + 1, (37, 23, channels), dtype=np.int64)
    codes[:20] = (np.arange(20)[:, None, None] * (hi // 40) + np.arange(23)[None, :, None]) % (hi + 1)
    codes[-1, :3] = np.array([0, hi, hi // 2])[:, None]
    codes = codes.astype(dtype)
    p = tmp_path / "a.png"
    with open(p, "wb") as f:
        png.write_png(f, codes if channels > 1 else codes[:, :, 0])
    np.testing.assert_array_equal(_oiio_codes(p), codes)
    pil = _pillow_codes(p)
    if not (dtype == np.uint16 and channels > 1):  # Pillow reads 16-bit colour as 8-bit
        np.testing.assert_array_equal(pil, codes)
    kinds = [k for k, _ in _chunks(p)]
    assert kinds[0] == b"IHDR" and kinds[-1] == b"IEND" and kinds[1:4] == [b"sRGB", b"gAMA", b"cHRM"]
    idat = [i for i, k in enumerate(kinds) if k == b"IDAT"]
    assert idat == list(range(idat[0], idat[0] + len(idat)))  # consecutive
    ihdr = dict(_chunks(p))[b"IHDR"]
    assert struct.unpack(">IIBBBBB", ihdr) == (23, 37, 8 * np.dtype(dtype).itemsize,
                                              png.COLOUR_TYPES[channels], 0, 0, 0)


def test_every_row_is_filtered_up(tmp_path):
    """The inflated stream is rows of filter byte 2 + the difference to the row above."""
    codes = np.random.default_rng(3).integers(0, 256, (9, 7, 3), dtype=np.uint8)
    p = tmp_path / "u.png"
    with open(p, "wb") as f:
        png.write_png(f, codes)
    raw = zlib.decompress(b"".join(d for k, d in _chunks(p) if k == b"IDAT"))
    rows = np.frombuffer(raw, np.uint8).reshape(9, 1 + 21)
    assert np.all(rows[:, 0] == 2)
    flat = codes.reshape(9, 21).astype(np.int64)
    want = (flat - np.vstack([np.zeros((1, 21), np.int64), flat[:-1]])) % 256
    np.testing.assert_array_equal(rows[:, 1:], want)


@pytest.mark.parametrize("level", [None, 0, 1, 6, 9])
def test_levels_and_the_zlib_fallback_give_the_same_pixels(tmp_path, monkeypatch, level):
    y, x = np.mgrid[0:64, 0:80]
    codes = np.stack([(x * 3) % 256, (y * 4) % 256, (x + y) % 256], axis=2).astype(np.uint8)
    sizes = {}
    for backend in ("default", "zlib only"):
        if backend == "zlib only":
            monkeypatch.setattr(png, "_isal", None)
        p = tmp_path / f"{backend}.png"
        with open(p, "wb") as f:
            png.write_png(f, codes, level=level)
        np.testing.assert_array_equal(_oiio_codes(p), codes)
        sizes[backend] = p.stat().st_size
    assert png.deflate_backend(level) == "zlib"  # isal patched out
    if level == 0:  # stored blocks: at least the raw filtered bytes
        assert sizes["default"] >= 64 * (1 + 80 * 3)


def test_compression_reaches_zlib_at_that_level(tmp_path):
    """``compression=N`` writes zlib level N (the stream header's FLEVEL field says so:
    0 for levels 0-1, 1 for 2-5, 2 for 6, 3 for 7-9); same pixels as the fast default."""
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:96, 0:128].astype(np.float32)
    img = np.stack([x / 128, y / 96, np.full_like(x, 0.3)], axis=2) ** 2
    img = np.clip(img + rng.normal(0, 0.002, img.shape), 0, 1).astype(np.float32)
    ref = None
    for level, flevel in ((None, None), (1, 0), (4, 1), (6, 2), (9, 3)):
        p = tmp_path / f"{level}.png"
        I.write_image(p, img, compression=level)
        stream = b"".join(d for k, d in _chunks(p) if k == b"IDAT")
        if flevel is not None:
            assert stream[1] >> 6 == flevel, (level, stream[:2])
        back, _ = I.read_image(p)
        if ref is None:
            ref = back
        np.testing.assert_array_equal(back, ref)


def test_bad_levels_and_formats_are_refused(tmp_path):
    with pytest.raises(ValueError, match="0..9"):
        png.write_png(open(tmp_path / "x.png", "wb"), np.zeros((2, 2), np.uint8), level=10)
    with pytest.raises(ValueError, match="uint8 or uint16"):
        png.write_png(open(tmp_path / "y.png", "wb"), np.zeros((2, 2), np.float32))
    with pytest.raises(ValueError, match="C in 1..4"):
        png.write_png(open(tmp_path / "z.png", "wb"), np.zeros((2, 2, 5), np.uint8))
    with pytest.raises(I.ImageFileError, match="PNG files only"):
        I.write_image(tmp_path / "a.jpg", np.zeros((2, 2, 3), np.float32), compression=3)
    with pytest.raises(ValueError, match="PNG files only"):
        I.write_data(tmp_path / "a.exr", np.zeros((2, 2), np.float32), compression=3)


def test_data_png_has_no_colour_chunks_and_round_trips(tmp_path):
    h = np.linspace(0, 300, 41 * 29, dtype=np.float32).reshape(41, 29)
    I.write_data(tmp_path / "h.png", h, white=300.0)
    assert [k for k, _ in _chunks(tmp_path / "h.png")][:2] == [b"IHDR", b"IDAT"]
    back = I.read_data(tmp_path / "h.png", white=300.0)
    np.testing.assert_allclose(back, h, atol=300.0 / 65535 / 2 + 1e-4)
    np.testing.assert_array_equal(_oiio_codes(tmp_path / "h.png")[:, :, 0],
                                  np.round(h / 300.0 * 65535).astype(np.uint16))
    I.write_data(tmp_path / "m8.png", h / 300.0, bit_depth=8)
    np.testing.assert_array_equal(_pillow_codes(tmp_path / "m8.png")[:, :, 0],
                                  np.round(h / 300.0 * 255).astype(np.uint8))


def test_colour_png_16bit_matches_the_exact_encode(tmp_path):
    """16-bit colour with alpha: straight sRGB codes round(65535 srgb(c / a)), alpha round(65535 a)."""
    rng = np.random.default_rng(5)
    a = rng.uniform(0.2, 1.0, (30, 40, 1)).astype(np.float32)
    c = rng.uniform(0.0, 1.0, (30, 40, 3)).astype(np.float32)
    I.write_image(tmp_path / "c.png", np.concatenate([c * a, a], axis=2), bit_depth=16)
    got = _oiio_codes(tmp_path / "c.png").astype(np.int64)
    want_c = np.round(I.linear_to_srgb((c * a) / a) * 65535)
    assert np.abs(got[:, :, :3] - want_c).max() <= 1
    np.testing.assert_array_equal(got[:, :, 3], np.round(a[:, :, 0] * 65535))
    assert dict(_chunks(tmp_path / "c.png"))[b"sRGB"] == b"\x00"


def test_save_image_node_compression_param(tmp_path):
    from pixgraph.session import Session

    g = tmp_path / "g.yaml"
    g.write_text("pixgraph: 1\nnodes:\n"
                 "  c: {type: pixgraph.Constant, params: {width: 64, height: 48, color: [0.2, 0.5, 0.8, 1.0]}}\n"
                 "  s: {type: pixgraph.SaveImage, inputs: {image: c.image}, params: {path: out.png, compression: 9}}\n"
                 "  j: {type: pixgraph.SaveImage, inputs: {image: c.image}, params: {path: out.jpg, compression: 9}}\n"
                 "outputs: {png: s.path, jpg: j.path}\n")
    s = Session()
    graph = s.load(str(g))
    s.run(graph, ["png"])
    img, _ = I.read_image(tmp_path / "out.png")
    np.testing.assert_allclose(img[0, 0], [0.2, 0.5, 0.8, 1.0], atol=0.004)
    with pytest.raises(Exception, match="compression"):
        s.run(graph, ["jpg"])
    assert not (tmp_path / "out.jpg").exists()


@pytest.mark.parametrize("ext", [".exr", ".tif"])
def test_the_same_image_gives_the_same_bytes_whatever_the_clock(tmp_path, ext, monkeypatch):
    """No time stamp in the header (OpenImageIO writes the time into EXR's capDate and
    TIFF's DateTime, as "YYYY:MM:DD HH:MM:SS"): no such string in the file, whenever it
    is written, so two writes are byte-identical (no sleep: the pattern is the check)."""
    import re
    import time

    from pixgraph_nodes.ops.imageio import write_image
    img = np.random.default_rng(1).uniform(0, 1, (8, 12, 3)).astype(np.float32)
    write_image(tmp_path / f"a{ext}", img)
    write_image(tmp_path / f"b{ext}", img)
    a, b = (tmp_path / f"a{ext}").read_bytes(), (tmp_path / f"b{ext}").read_bytes()
    assert a == b
    assert time.strftime("%Y:%m:%d").encode() not in a
    assert not re.search(rb"\d{4}:\d{2}:\d{2} \d{2}:\d{2}:\d{2}", a)
