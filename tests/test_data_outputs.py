"""Data outputs stay data: mattes, darkness and pixel heights written to files read back
as the same numbers (exact for float formats, within quantisation for integer ones),
never gamma-encoded or clipped."""
import numpy as np
import pytest

from pixgraph import cli
from pixgraph.session import Session
from pixgraph_nodes.ops.heightmaps import load_pixel_height
from pixgraph_nodes.ops.imageio import read_data, read_image, read_mask, write_data

HEIGHTS = np.array([[0.0, 0.5, 1.0], [37.25, 300.5, 1234.0]], np.float32)
DARK = np.array([[0.0, 0.156, 0.5], [0.999, 1.0, 0.0312]], np.float32)


@pytest.mark.parametrize("ext", ["npy", "exr", "tif"])
def test_float_formats_are_exact(tmp_path, ext):
    for arr in (HEIGHTS, DARK):
        write_data(tmp_path / f"m.{ext}", arr)
        np.testing.assert_array_equal(read_data(tmp_path / f"m.{ext}"), arr)
    np.testing.assert_array_equal(load_pixel_height(tmp_path / f"m.{ext}"), DARK)


def test_png_is_linear_and_within_quantisation(tmp_path):
    write_data(tmp_path / "d.png", DARK)
    np.testing.assert_allclose(read_data(tmp_path / "d.png"), DARK, atol=0.5 / 65535 + 1e-7)
    np.testing.assert_allclose(read_mask(tmp_path / "d.png"), DARK, atol=0.5 / 65535 + 1e-7)
    write_data(tmp_path / "d8.png", DARK, bit_depth=8)
    np.testing.assert_allclose(read_data(tmp_path / "d8.png"), DARK, atol=0.5 / 255 + 1e-7)
    # heights in a PNG: full white is `white` pixels; LoadPixelHeight's scale reads them back
    write_data(tmp_path / "h.png", HEIGHTS, white=2048.0)
    np.testing.assert_allclose(load_pixel_height(tmp_path / "h.png", 2048.0), HEIGHTS, atol=0.5 * 2048 / 65535 + 1e-4)
    with pytest.raises(ValueError, match=r"0\.\.1234.*npy"):
        write_data(tmp_path / "h.png", HEIGHTS)     # never clipped: refused


GRAPH = """pixgraph: 1
nodes:
  d: {type: pixgraph.LoadMask, params: {path: dark.npy}}
  h: {type: pixgraph.LoadPixelHeight, params: {path: heights.npy}}
  save_h: {type: pixgraph.SaveImage, inputs: {image: h.height}, params: {path: out/h.png, white: 2048}}
  save_d: {type: pixgraph.SaveImage, inputs: {image: d.mask}, params: {path: out/d.exr}}
outputs: {darkness: d.mask, height: h.height, saved_h: save_h.path, saved_d: save_d.path}
"""


def test_cli_and_save_image_write_data_as_data(tmp_path, capsys):
    np.save(tmp_path / "dark.npy", DARK)
    np.save(tmp_path / "heights.npy", HEIGHTS)
    (tmp_path / "g.yaml").write_text(GRAPH)
    g = str(tmp_path / "g.yaml")
    for outs in ([f"darkness={tmp_path}/o/d.png", f"height={tmp_path}/o/h.npy"], [f"height={tmp_path}/o/h.exr"]):
        argv = ["run", g, "--no-disk-cache", "-q"]
        for o in outs:
            argv += ["-o", o]
        assert cli.main(argv) == 0, capsys.readouterr().err
    # before: a darkness of 0.156 came back as 0.431 (sRGB-encoded 8-bit PNG)
    np.testing.assert_allclose(read_data(tmp_path / "o/d.png"), DARK, atol=0.5 / 65535 + 1e-7)
    np.testing.assert_array_equal(np.load(tmp_path / "o/h.npy"), HEIGHTS)
    np.testing.assert_array_equal(read_data(tmp_path / "o/h.exr"), HEIGHTS)
    # heights to a PNG from the command line would clip: refused, one line, exit 2
    assert cli.main(["run", g, "--no-disk-cache", "-q", "-o", f"height={tmp_path}/o/h.png"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "1234" in err[0] and ".npy" in err[0]
    # the SaveImage sinks: a 2-D array is data
    assert cli.main(["run", g, "--no-disk-cache", "-q", "-o", f"darkness={tmp_path}/x.png"]) == 0
    Session(disk_cache=None).run(g, outputs=["saved_h", "saved_d"])
    np.testing.assert_allclose(load_pixel_height(tmp_path / "out/h.png", 2048.0), HEIGHTS, atol=2048 / 65535)
    np.testing.assert_array_equal(read_data(tmp_path / "out/d.exr"), DARK)


def test_colour_images_still_encode_srgb(tmp_path):
    """A colour image to PNG stays sRGB (what a viewer expects); .npy keeps the floats."""
    from pixgraph_nodes.ops.imageio import write_image
    img = np.full((2, 2, 3), 0.2158605, np.float32)
    write_image(tmp_path / "c.png", img)
    np.testing.assert_allclose(read_data(tmp_path / "c.png"), 128 / 255, atol=1e-6)   # stored sRGB 128
    np.testing.assert_allclose(read_image(tmp_path / "c.png")[0], img, atol=2e-3)
    write_image(tmp_path / "c.npy", img)
    np.testing.assert_array_equal(np.load(tmp_path / "c.npy"), img)
