"""Editing pixel heights by hand (nodes/ops/height_edit.py, pixgraph.PixelHeightEdit): analytic cases."""
import math

import numpy as np
import pytest

from pixgraph.node import InputError, Namespace
from pixgraph_nodes.ops import height_edit as he
from pixgraph_nodes.ops.heightmaps import contact_line_height
from pixgraph_nodes.pixel_height_edit import PixelHeightEdit


def grid(H, W):
    v, u = np.mgrid[0:H, 0:W] + 0.5
    return u, v


def run(height, mask, **p):
    params = Namespace(PixelHeightEdit.spec.coerce_params(p))
    return PixelHeightEdit().compute(None, Namespace({"height": height, "mask": mask}), params)["height"]


def test_one_contact_point_shifts_by_its_height():
    H, W = 60, 40
    u, v = grid(H, W)
    h = 3.0 + 0.5 * u + 0.25 * v            # a plane: bilinear sampling is exact on it
    m = np.ones((H, W), bool)
    out = he.edit_pixel_height(h, m, [(10.5, 50.5)])
    np.testing.assert_allclose(out, np.maximum(h - (3.0 + 0.5 * 10.5 + 0.25 * 50.5), 0), atol=1e-4)
    assert abs(he.sample_height(out, 10.5, 50.5)) < 1e-4


def test_two_contact_points_remove_a_ramp_across_the_columns_only():
    H, W = 50, 80
    u, v = grid(H, W)
    h = 40.0 + 0.3 * u                      # a map that rises to the right: the right foot 'floats'
    c = he.contact_correction(h, [(10.5, 45.5), (70.5, 45.5)])
    np.testing.assert_allclose(c, 40.0 + 0.3 * u, atol=1e-6)
    # a slanted line: the offset goes through both points' heights and is constant up each column
    p1, p2 = np.array([10.5, 40.5]), np.array([50.5, 20.5])
    hh = 2.0 * u - 1.0 * v
    c2 = he.contact_correction(hh, [tuple(p1), tuple(p2)])
    for p in (p1, p2):
        assert abs(he.sample_height(c2, *p) - he.sample_height(hh, *p)) < 1e-6
    np.testing.assert_allclose(c2, np.broadcast_to(c2[:1], c2.shape), atol=1e-9)
    # two points in one column, or closer than a tenth of the object's width: their mean
    for pts, width in (([(30.5, 10.5), (30.5, 40.5)], None), ([(30.5, 10.5), (31.0, 40.5)], 60.0)):
        c3 = he.contact_correction(hh, pts, width)
        np.testing.assert_allclose(c3, np.mean([he.sample_height(hh, *p) for p in pts]))
    c3 = he.contact_correction(hh, [(30.5, 10.5), (30.5, 40.5)])
    np.testing.assert_allclose(c3, (he.sample_height(hh, 30.5, 10.5) + he.sample_height(hh, 30.5, 40.5)) / 2)


def test_three_feet_remove_the_least_squares_column_offset_and_keep_the_slope_up_the_object():
    H, W = 64, 64
    u, v = grid(H, W)
    truth = np.maximum(60.5 - v, 0.0)              # an upright object, contact at row 60.5
    m = np.ones((H, W), bool)
    # front feet on the contact row, a back foot 12 rows up that the map gives 12 px (it took it
    # for the body): a plane through the three would tilt by 1 px per row and wipe the map
    h = truth + 5.0 + 0.2 * u                      # the object floats, more to the right
    feet = [(10.5, 60.5), (50.5, 60.5), (30.5, 48.5)]
    out = he.edit_pixel_height(h, m, feet)
    hs = np.array([he.sample_height(h, *f) for f in feet])
    fu = np.array([f[0] for f in feet])
    A = np.c_[np.ones(3), fu]
    a, b = np.linalg.lstsq(A, hs, rcond=None)[0]
    np.testing.assert_allclose(out, np.maximum(h - (a + b * u), 0), atol=1e-4)
    # the slope up each column is the input's: one px per row above the contact
    assert np.allclose(np.diff(out[10:40, 32]), -1.0, atol=1e-4)
    # the residuals at the feet are the least-squares ones (they sum to 0)
    assert abs(sum(he.sample_height(h, *f) - (a + b * f[0]) for f in feet)) < 1e-6
    assert out[5, 32] > 40


def test_upright_mode_is_the_contact_line_model():
    H, W = 80, 60
    m = np.zeros((H, W), bool)
    m[10:70, 20:40] = True                            # bottom edge of the lowest row: v = 70
    out = he.edit_pixel_height(np.zeros((H, W)), m, [(25.0, 70.0), (35.0, 70.0)], contact_mode="upright")
    np.testing.assert_allclose(out[m], contact_line_height(m.astype(np.float32))[m], atol=0.51)
    _, v = grid(H, W)
    np.testing.assert_allclose(out[m], (70.0 - v)[m], atol=1e-5)
    # a sloping ground line through two feet: v_line = 70 + 0.5 (u - 25)
    out2 = he.edit_pixel_height(np.zeros((H, W)), m, [(25.0, 70.0), (35.0, 75.0)], contact_mode="upright")
    u, v = grid(H, W)
    np.testing.assert_allclose(out2[m], np.maximum(70 + 0.5 * (u - 25) - v, 0)[m], atol=1e-5)


def test_lying_caps_the_column_distance_at_the_thickness():
    H, W = 40, 100
    m = np.zeros((H, W), bool)
    m[20:36, 10:90] = True                           # a long low box: column extent 16
    out = he.edit_pixel_height(np.full((H, W), 50.0), m, lying=True, thickness=5.0)
    _, v = grid(H, W)
    np.testing.assert_allclose(out[m], np.minimum(36 - v, 5.0)[m], atol=1e-6)
    auto = he.edit_pixel_height(np.full((H, W), 50.0), m, lying=True)
    assert auto[m].max() == pytest.approx(8.0)       # half the median column extent


def test_tilt_scales_heights_by_the_orthographic_factor():
    H, W = 50, 30
    m = np.ones((H, W), bool)
    h = np.full((H, W), 30.0)
    out = he.edit_pixel_height(h, m, tilt_deg=30.0, elevation_deg=20.0)
    g = 1 / (1 + math.tan(math.radians(30)) * math.tan(math.radians(20)))
    np.testing.assert_allclose(out, 30.0 * g, rtol=1e-6)
    # leaning toward the camera makes heights larger; no elevation, no change
    assert he.edit_pixel_height(h, m, tilt_deg=-30.0)[0, 0] > 30.0
    np.testing.assert_allclose(he.edit_pixel_height(h, m, tilt_deg=40.0, elevation_deg=0.0), h)
    with pytest.raises(ValueError, match="view ray"):
        he.tilt_gain(-80.0, 80.0)


def test_lift_and_mask():
    h = np.arange(12, dtype=np.float32).reshape(3, 4)
    m = h > 4
    out = he.edit_pixel_height(h, m, lift=2.5)
    np.testing.assert_allclose(out, np.where(m, h + 2.5, 0.0))


def test_node_checks_its_params_and_matches_the_function():
    H, W = 30, 20
    u, v = grid(H, W)
    h = (30.0 - v).astype(np.float32) + 4.0
    m = np.ones((H, W), np.float32)
    out = run(h, m, contact_points=[10.0, 29.5])
    np.testing.assert_allclose(out, np.maximum(30.0 - v - 0.5, 0), atol=1e-4)
    with pytest.raises(InputError, match="even count"):
        run(h, m, contact_points=[1.0, 2.0, 3.0])
    with pytest.raises(InputError, match="outside the 20x30"):
        run(h, m, contact_points=[25.0, 5.0])
    with pytest.raises(InputError, match="same size"):
        run(h, np.ones((10, 10), np.float32))


def test_graph_saves_the_edit_and_a_preview_scales_its_points(tmp_path):
    from pixgraph.session import Session
    g = tmp_path / "g.yaml"
    g.write_text("""pixgraph: 1
nodes:
  m: {type: pixgraph.InputMask}
  h: {type: pixgraph.InputPixelHeight}
  e: {type: pixgraph.PixelHeightEdit, inputs: {height: h.height, mask: m.mask},
      params: {contact_points: [20, 60, 60, 60], contact_mode: upright, lift: 4}}
outputs: {out: e.height}
""")
    H, W = 80, 80
    m = np.zeros((H, W), np.float32)
    m[10:60, 20:60] = 1
    s = Session()
    out = s.run(g, bind={"m": m, "h": np.zeros((H, W), np.float32)})["out"]
    _, v = grid(H, W)
    np.testing.assert_allclose(out[m > 0], (60.0 - v + 4.0)[m > 0], atol=1e-5)
    # a half-size preview: the points (in px) and the lift scale with the image
    half = s.run(g, bind={"m": m[::2, ::2].copy(), "h": np.zeros((40, 40), np.float32)}, scale=0.5)["out"]
    _, v2 = grid(40, 40)
    mh = m[::2, ::2] > 0
    np.testing.assert_allclose(half[mh], (30.0 - v2 + 2.0)[mh], atol=1e-5)


def test_shift_with_two_feet_a_pixel_apart_does_not_tilt_the_map():
    """A pole's front and back foot, 0.5 px apart in u, heights 10 and 2: one place, shifted
    by their mean; a line through them would tilt the map by 16 px per px (the review's
    case: heights up to 940 and half the mask zeroed)."""
    H, W = 200, 60
    u, v = grid(H, W)
    m = np.zeros((H, W), bool)
    m[20:180, 20:40] = True
    truth = np.where(m, 179.5 - v, 0.0)
    h = truth.copy()
    h[176:180, 29] = 10.0
    h[176:180, 30] = 2.0
    out = he.edit_pixel_height(h, m, [(29.5, 178.0), (30.0, 178.0)], "shift")
    shift = (he.sample_height(h, 29.5, 178.0) + he.sample_height(h, 30.0, 178.0)) / 2
    np.testing.assert_allclose(out, np.where(m, np.maximum(h - shift, 0), 0), atol=1e-4)
    assert out.max() < truth.max() and (out[m] > 0).mean() > 0.9
