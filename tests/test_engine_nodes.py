"""The engine's first nodes: Constant, Merge, LoadImage, SaveImage (GaussianBlur: test_engine_blur.py)."""
import numpy as np
import pytest

from pixgraph import fileio
from pixgraph.session import Session
from pixgraph_nodes.merge import merge, to_rgba
from pixgraph_nodes.ops import imageio as io


@pytest.fixture(scope="module")
def session():
    return Session(cache_bytes=1 << 28)


def test_constant_is_premultiplied(session):
    b = session.builder()
    b.add("pixgraph.Constant", "c", color=[0.8, 0.4, 0.2, 0.5], width=3, height=2)
    b.output("o", "c.image")
    img = session.run(b.build())["o"]
    assert img.shape == (2, 3, 4)
    np.testing.assert_allclose(img[1, 2], [0.4, 0.2, 0.1, 0.5])


def test_merge_modes_analytic():
    a = np.zeros((1, 1, 4), np.float32) + np.float32([0.2, 0.1, 0.0, 0.25])  # premultiplied
    b = np.zeros((1, 1, 4), np.float32) + np.float32([0.4, 0.8, 0.6, 1.0])
    np.testing.assert_allclose(merge(a, b, "over", 1.0)[0, 0], [0.2 + 0.3, 0.1 + 0.6, 0.45, 1.0], atol=1e-7)
    np.testing.assert_allclose(merge(a, b, "add", 1.0)[0, 0], [0.6, 0.9, 0.6, 1.25], atol=1e-7)
    np.testing.assert_allclose(merge(a, b, "multiply", 1.0)[0, 0], [0.08, 0.08, 0.0, 0.25], atol=1e-7)
    np.testing.assert_allclose(merge(a, b, "mix", 0.25)[0, 0], 0.75 * b[0, 0] + 0.25 * a[0, 0], atol=1e-7)
    np.testing.assert_array_equal(merge(a, b, "over", 0.0), b)
    with pytest.raises(ValueError, match="A is 2x1 but B is 1x1"):
        merge(np.zeros((1, 2, 4), np.float32), b, "over", 1.0)


def test_to_rgba_promotes_masks_and_grey():
    m = np.float32([[0.5]])
    np.testing.assert_array_equal(to_rgba(m)[0, 0], [0.5, 0.5, 0.5, 1.0])
    ga = np.float32([[[0.3, 0.6]]])
    np.testing.assert_array_equal(to_rgba(ga)[0, 0], np.float32([0.3, 0.3, 0.3, 0.6]))
    np.testing.assert_array_equal(to_rgba(np.float32([[[1, 2, 3]]]))[0, 0], [1, 2, 3, 1])


def test_load_save_round_trip_in_a_graph(session, tmp_path):
    rng = np.random.default_rng(7)
    a = rng.uniform(0.05, 1, (5, 6)).astype(np.float32)
    straight = rng.uniform(0, 1, (5, 6, 3)).astype(np.float32)
    premult = np.concatenate([straight * a[..., None], a[..., None]], axis=2)
    io.write_image(tmp_path / "in.png", premult, bit_depth=16)
    (tmp_path / "g.yaml").write_text(
        "pixgraph: 1\n"
        "nodes:\n"
        "  load: {type: pixgraph.LoadImage, params: {path: in.png}}\n"
        "  save: {type: pixgraph.SaveImage, inputs: {image: load.image}, params: {path: out/out.exr}}\n"
        "outputs: {image: load.image, alpha: load.alpha, file: save.path}\n")
    (tmp_path / "out").mkdir()
    g = fileio.load(tmp_path / "g.yaml", session.registry)
    out = session.run(g, outputs=["image", "alpha"])
    assert not (tmp_path / "out" / "out.exr").exists()  # the sink was not requested
    np.testing.assert_allclose(out["image"], premult, atol=1e-4)
    np.testing.assert_allclose(out["alpha"], a, atol=1e-4)
    path = session.run(g, outputs=["file"])["file"]
    assert path == str(tmp_path / "out" / "out.exr")
    back, _ = io.read_image(path)
    np.testing.assert_array_equal(back, out["image"])


def test_load_image_colorspace_param(session, tmp_path):
    grey = np.full((2, 2, 3), io.srgb_to_linear(np.float32(0.5)), np.float32)
    io.write_image(tmp_path / "g.png", grey, bit_depth=16)
    b = session.builder(base_dir=str(tmp_path))
    b.add("pixgraph.LoadImage", "srgb", path="g.png")
    b.add("pixgraph.LoadImage", "raw", path="g.png", colorspace="linear")
    b.output("a", "srgb.image")
    b.output("b", "raw.image")
    out = session.run(b.build())
    np.testing.assert_allclose(out["a"], 0.21404, atol=1e-4)  # decoded to linear
    np.testing.assert_allclose(out["b"], 0.5, atol=1e-4)      # file values as they are


def test_example_graph_blur_over(tmp_path):
    """graphs/blur_over.yaml, through the CLI: the cutout over the photo, and its sink."""
    import pathlib
    import shutil

    from pixgraph.cli import main

    src = pathlib.Path(__file__).resolve().parents[1] / "graphs"
    (tmp_path / "assets").mkdir()
    for f in ("figure.png", "room_ground.jpg"):
        shutil.copy(src / "assets" / f, tmp_path / "assets" / f)
    shutil.copy(src / "blur_over.yaml", tmp_path / "g.yaml")
    (tmp_path / "out").mkdir()
    assert main(["run", str(tmp_path / "g.yaml"), "--no-disk-cache", "-q", "-o",
                 f"final={tmp_path / 'final.exr'}"]) == 0
    assert not (tmp_path / "out" / "blur_over.png").exists()  # -o asks for 'final' only
    assert main(["run", str(tmp_path / "g.yaml"), "--no-disk-cache", "-q"]) == 0
    png, alpha = io.read_image(tmp_path / "out" / "blur_over.png")
    final, _ = io.read_image(tmp_path / "final.exr")
    photo, _ = io.read_image(tmp_path / "assets" / "room_ground.jpg")
    cut, cut_alpha = io.read_image(tmp_path / "assets" / "figure.png")
    assert png.shape[:2] == final.shape[:2] == photo.shape[:2] and np.all(alpha == 1.0)
    far = cut_alpha == 0  # far from the figure (before blurring) the photo shows through
    from scipy.ndimage import binary_erosion
    far = binary_erosion(far, iterations=8)
    np.testing.assert_allclose(final[far][:, :3], photo[far], atol=1e-5)
    np.testing.assert_allclose(png[..., :3], final[..., :3], atol=0.01)  # 8-bit sRGB quantisation
