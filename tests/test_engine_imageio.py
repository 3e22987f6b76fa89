"""Image file I/O: colour encoding, alpha association and round trips (nodes/ops/imageio.py)."""
import numpy as np
import pytest

from pixgraph_nodes.ops import imageio as io


def test_srgb_transfer_known_values_and_inverse():
    # 0.5 display value is 0.21404 linear (IEC 61966-2-1); the toe is linear
    assert io.srgb_to_linear(np.float32(0.5)) == pytest.approx(0.214041, abs=1e-5)
    assert io.srgb_to_linear(np.float32(0.04)) == pytest.approx(0.04 / 12.92, rel=1e-6)
    x = np.linspace(0, 1, 1001, dtype=np.float32)
    np.testing.assert_allclose(io.linear_to_srgb(io.srgb_to_linear(x)), x, atol=2e-6)


def _semi_transparent():
    rng = np.random.default_rng(1)
    straight = rng.uniform(0, 1, (6, 7, 3)).astype(np.float32)
    a = rng.uniform(0.1, 1, (6, 7)).astype(np.float32)
    a[0, 0] = 0.0
    a[1, 1] = 1.0
    premult = np.concatenate([straight * a[..., None], a[..., None]], axis=2)
    return premult, a


@pytest.mark.parametrize("ext,bits,tol", [(".png", 8, 3e-3), (".png", 16, 3e-5), (".tif", 16, 3e-5)])
def test_png_tiff_round_trip_semi_transparent(tmp_path, ext, bits, tol):
    premult, a = _semi_transparent()
    p = tmp_path / f"x{ext}"
    io.write_image(p, premult, bit_depth=bits)
    img, alpha = io.read_image(p)
    assert img.dtype == np.float32 and img.shape == premult.shape
    np.testing.assert_allclose(alpha, a, atol=1 / (2 ** bits - 1))
    # tolerance in linear premultiplied units; quantisation happens on sRGB values
    np.testing.assert_allclose(img, premult, atol=tol * 4)


def test_png_file_holds_straight_srgb(tmp_path):
    # half-covered mid grey: the file must hold straight sRGB 0.5 -> 128, alpha 128
    lin = float(io.srgb_to_linear(np.float32(128 / 255)))
    img = np.array([[[lin * 0.5, lin * 0.5, lin * 0.5, 0.5]]], np.float32)
    p = tmp_path / "g.png"
    io.write_image(p, img)
    import OpenImageIO as oiio
    cfg = oiio.ImageSpec()
    cfg.attribute("oiio:UnassociatedAlpha", 1)
    inp = oiio.ImageInput.open(str(p), cfg)
    raw = inp.read_image("uint8")
    inp.close()
    assert raw[0, 0].tolist() == [128, 128, 128, 128]


def test_read_premultiplied_file_and_linear_flag(tmp_path):
    premult, a = _semi_transparent()
    p = tmp_path / "x.exr"
    io.write_image(p, premult)
    img, alpha = io.read_image(p)  # auto: EXR holds linear, premultiplied values
    np.testing.assert_array_equal(img, premult)
    np.testing.assert_array_equal(alpha, a)
    img2, _ = io.read_image(p, alpha="premultiplied")
    np.testing.assert_array_equal(img2, premult)
    img3, _ = io.read_image(p, alpha="straight")
    np.testing.assert_allclose(img3[..., :3], premult[..., :3] * a[..., None], atol=1e-7)


def test_exr_half_and_channels_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    ch = {"hard_shadow": rng.uniform(0, 1, (5, 4)).astype(np.float32),
          "pixel_height": rng.uniform(0, 300, (5, 4)).astype(np.float32)}
    p = tmp_path / "b.exr"
    io.write_exr_channels(p, ch)
    back = io.read_exr_channels(p)
    assert list(back) == ["hard_shadow", "pixel_height"]
    for k in ch:
        np.testing.assert_array_equal(back[k], ch[k])
    io.write_image(tmp_path / "h.exr", ch["hard_shadow"], bit_depth=16)
    img, alpha = io.read_image(tmp_path / "h.exr")
    assert img.shape == (5, 4, 1) and np.all(alpha == 1)
    np.testing.assert_allclose(img[..., 0], ch["hard_shadow"], rtol=1e-3)


def test_jpeg_drops_alpha_and_bad_extension(tmp_path):
    premult, _ = _semi_transparent()
    io.write_image(tmp_path / "x.jpg", premult)
    img, alpha = io.read_image(tmp_path / "x.jpg")
    assert img.shape == (6, 7, 3) and np.all(alpha == 1)
    with pytest.raises(ValueError, match="unsupported image extension"):
        io.write_image(tmp_path / "x.bmpx", premult)
    with pytest.raises(OSError):
        io.read_image(tmp_path / "missing.png")


def test_8bit_files_decode_and_encode_by_table(tmp_path):
    """8-bit files are decoded by a table of the 256 codes (the same numbers as the
    float decode) and written by a table of 65536 linear levels (within one code of
    rounding the exact encode, off by one only at a code's boundary)."""
    from pixgraph_nodes.ops import imageio as I
    rng = np.random.default_rng(1)
    x = (rng.random((120, 160, 3), dtype=np.float32) ** 2.2).astype(np.float32)
    I.write_image(tmp_path / "a.png", x)
    data, _ = I._read_float(I._oiio(), tmp_path / "a.png", keep_uint8=True)
    assert data.dtype == np.uint8
    ref = np.round(I.linear_to_srgb(x) * 255.0)
    diff = np.abs(data.astype(np.float64) - ref)
    assert diff.max() <= 1 and (diff > 0).mean() < 0.01
    image, alpha = I.read_image(tmp_path / "a.png")
    want, _ = I.to_internal(data.astype(np.float32) / 255.0, "srgb", "straight")
    np.testing.assert_array_equal(image, want)
    assert alpha.shape == (120, 160) and np.all(alpha == 1.0)
    # RGBA: straight 8-bit codes, premultiplied on read like the float path
    xa = np.concatenate([x * 0.5, np.full((120, 160, 1), 0.5, np.float32)], axis=2)
    I.write_image(tmp_path / "b.png", xa)
    image, alpha = I.read_image(tmp_path / "b.png")
    config = I._oiio().ImageSpec()
    config.attribute("oiio:UnassociatedAlpha", 1)           # the file's straight codes, as read_image asks
    data, _ = I._read_float(I._oiio(), tmp_path / "b.png", config, keep_uint8=True)
    want, wa = I.to_internal(data.astype(np.float32) / 255.0, "srgb", "straight")
    np.testing.assert_array_equal(image, want)
    np.testing.assert_array_equal(alpha, wa)
