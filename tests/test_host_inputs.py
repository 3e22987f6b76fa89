"""Host inputs: a host binds numpy arrays to input nodes; every output comes from the array."""
import numpy as np
import pytest

from pixgraph import cli
from pixgraph.engine import NodeInputError
from pixgraph.graph import GraphError
from pixgraph.session import Session


@pytest.fixture(scope="module")
def session():
    return Session(disk_cache=None)


def _passthrough(session, type_id, outputs, **params):
    b = session.builder()
    b.add(type_id, "inp", **params)
    for o in outputs:
        b.output(o, f"inp.{o}")
    return b.build()


def test_rgba_image_gives_image_and_alpha(session):
    g = _passthrough(session, "pixgraph.InputImage", ["image", "alpha"])
    rgba = np.random.default_rng(0).random((5, 7, 4)).astype(np.float32)
    rgba[..., :3] *= rgba[..., 3:]                      # premultiplied
    out = session.run(g, bind={"inp": rgba})
    np.testing.assert_array_equal(out["image"], rgba)
    np.testing.assert_array_equal(out["alpha"], rgba[..., 3])


def test_straight_srgb_uint8_is_decoded_then_premultiplied(session):
    g = _passthrough(session, "pixgraph.InputImage", ["image", "alpha"], colorspace="srgb", alpha="straight")
    px = np.array([[[255, 188, 0, 128]]], np.uint8)      # sRGB 188/255 = 0.50 linear
    out = session.run(g, bind={"inp": px})
    a = 128 / 255
    lin = ((188 / 255 + 0.055) / 1.055) ** 2.4
    np.testing.assert_allclose(out["image"][0, 0], [a, lin * a, 0.0, a], rtol=1e-6)
    np.testing.assert_allclose(out["alpha"][0, 0], a, rtol=1e-6)


def test_rgb_background_has_unit_alpha(session):
    g = _passthrough(session, "pixgraph.InputImage", ["image", "alpha"])
    out = session.run(g, bind={"inp": np.full((3, 4, 3), 0.25, np.float64)})
    assert out["image"].dtype == np.float32 and out["image"].shape == (3, 4, 3)
    assert np.all(out["alpha"] == 1.0)


def test_mask_and_pixel_height(session):
    gm = _passthrough(session, "pixgraph.InputMask", ["mask"])
    m = session.run(gm, bind={"inp": np.array([[0, 255], [51, 1000 // 4]], np.uint16)})["mask"]
    np.testing.assert_allclose(m, np.array([[0, 255], [51, 250]]) / 65535, rtol=1e-6)
    gh = _passthrough(session, "pixgraph.InputPixelHeight", ["height"])
    h = np.array([[0.0, 300.5]], np.float64)
    np.testing.assert_array_equal(session.run(gh, bind={"inp": h})["height"], h.astype(np.float32))


@pytest.mark.parametrize("type_id,value,match", [
    ("pixgraph.InputPixelHeight", np.zeros((2, 2), np.uint8), "float"),
    ("pixgraph.InputMask", np.zeros((2, 2, 3), np.float32), "shape"),
    ("pixgraph.InputImage", np.zeros((2, 2, 5), np.float32), "shape"),
    ("pixgraph.InputImage", [[1, 2]], "numpy array"),
    ("pixgraph.InputImage", np.zeros((2, 2), np.int32), "dtype"),
])
def test_bad_arrays_are_graph_errors_naming_the_node(session, type_id, value, match):
    g = _passthrough(session, type_id, [session.registry.get(type_id).outputs[0].name])
    with pytest.raises(GraphError, match=match) as e:
        session.run(g, bind={"inp": value})
    assert e.value.node == "inp"


def test_unbound_host_input_is_bad_input(session, tmp_path, capsys):
    g = _passthrough(session, "pixgraph.InputMask", ["mask"])
    with pytest.raises(NodeInputError, match="bind"):
        session.run(g)
    path = tmp_path / "g.yaml"
    path.write_text("pixgraph: 1\nnodes:\n  m: {type: pixgraph.InputMask}\noutputs: {o: m.mask}\n")
    assert cli.main(["run", str(path), "--no-disk-cache", "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'m'" in err[0] and "bind" in err[0]


def test_bound_key_follows_array_and_params(session):
    g1 = _passthrough(session, "pixgraph.InputImage", ["image"])
    g2 = _passthrough(session, "pixgraph.InputImage", ["image"], alpha="straight")
    rgba = np.full((2, 2, 4), 0.5, np.float32)
    k1 = session.plan(g1, bind={"inp": rgba}).keys["inp"]
    assert session.plan(g1, bind={"inp": rgba.copy()}).keys["inp"] == k1
    assert session.plan(g2, bind={"inp": rgba}).keys["inp"] != k1
    other = rgba.copy()
    other[0, 0, 0] = 0.25
    assert session.plan(g1, bind={"inp": other}).keys["inp"] != k1
    # the two readings really differ: straight colour is premultiplied on the way in
    assert session.run(g2, bind={"inp": rgba})["image"][0, 0, 0] == pytest.approx(0.25)
    assert session.run(g1, bind={"inp": rgba})["image"][0, 0, 0] == pytest.approx(0.5)


def test_load_image_bound_gives_both_outputs_without_reading_its_file(session, tmp_path):
    rgba = np.zeros((4, 4, 4), np.float32)
    rgba[1:3, 1:3] = [0.5, 0.25, 0.0, 1.0]
    b = session.builder(base_dir=str(tmp_path))
    (tmp_path / "x.png").write_bytes(b"not a png")      # the graph needs the file; bound, it is never read
    b.add("pixgraph.LoadImage", "c", path=str(tmp_path / "x.png"))
    b.output("image", "c.image")
    b.output("alpha", "c.alpha")
    out = session.run(b.build(), bind={"c": rgba})
    np.testing.assert_array_equal(out["image"], rgba)
    np.testing.assert_array_equal(out["alpha"], rgba[..., 3])
