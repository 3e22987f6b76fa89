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


# -- foot depth (step 2b), the body ring and the lying thickness ------------------------------

def test_foot_depth_moves_the_bodys_ground_line_and_keeps_the_contact():
    """Above 2|D| px of height, the height above a ground line D rows lower (D > 0: in
    front of the contact) or higher (D < 0: behind it); below, a straight ramp from the
    contact (0) to 2|D| + D."""
    H, W = 120, 40
    _, v = grid(H, W)
    m = np.zeros((H, W), bool)
    m[10:100, 5:35] = True
    h = np.where(m, 100.0 - v, 0.0)                   # upright, contact line at row 100
    for D in (12.0, 30.0, -10.0, -20.0):
        out = he.edit_pixel_height(h, m, foot_depth=D)
        body = m & (h >= 2 * abs(D))
        np.testing.assert_allclose(out[body], ((100.0 + D) - v)[body], atol=1e-4)
        low = m & (h < 2 * abs(D))
        slope = (2 * abs(D) + D) / (2 * abs(D))      # 3/2 in front, 1/2 behind
        np.testing.assert_allclose(out[low], slope * h[low], atol=1e-4)
        assert out[99, 20] == pytest.approx(0.5 * slope, abs=1e-4)     # the contact row stays ~0
    # continuous and strictly increasing up each column (no step at 2|D|)
    for D in (25.0, -25.0):
        col = he.edit_pixel_height(h, m, foot_depth=D)[10:100, 20]
        assert (np.diff(col) < 0).all() and np.abs(np.diff(col)).max() <= 1.5 + 1e-6
    # lying ignores it; outside the mask stays 0; 0 is the identity
    lying = he.edit_pixel_height(h, m, lying=True, thickness=30.0)
    np.testing.assert_array_equal(he.edit_pixel_height(h, m, lying=True, thickness=30.0, foot_depth=15.0), lying)
    assert (he.edit_pixel_height(h, m, foot_depth=15.0)[~m] == 0).all()
    assert he.is_identity(foot_depth=0.0) and not he.is_identity(foot_depth=0.5)


@pytest.mark.parametrize("depth", [-30.0, -5.0, 0.0, 8.0, 40.0])
@pytest.mark.parametrize("tilt,lift", [(0.0, 0.0), (25.0, 0.0), (-15.0, 6.0)])
def test_body_point_and_depth_for_height_invert_the_edit(depth, tilt, lift):
    H, W = 90, 70
    mask = np.zeros((H, W), bool)
    mask[20:80, 10:60] = True
    mask[20:50, 30:40] = False                       # a notch: the centroid's pixel is not covered
    _, v = grid(H, W)
    height = np.where(mask, 80.0 - v, 0.0)
    edited = he.edit_pixel_height(height, mask, tilt_deg=tilt, elevation_deg=25.0, lift=lift, foot_depth=depth)
    u, vv, h, h0 = he.body_point(mask, edited, tilt, 25.0, lift, depth)
    r, c = int(vv), int(u)
    assert mask[r, c] and (u, vv) == (c + 0.5, r + 0.5)
    ys, xs = np.nonzero(mask)
    assert (r - ys.mean()) ** 2 + (c - xs.mean()) ** 2 == pytest.approx(
        ((ys - ys.mean()) ** 2 + (xs - xs.mean()) ** 2).min())
    assert h == pytest.approx(float(edited[r, c]), abs=1e-4)
    assert h0 == pytest.approx(height[r, c], abs=1e-3)    # its height before depth, tilt and lift
    g = he.tilt_gain(tilt, 25.0)
    D0 = he.depth_for_height(h0, h, g, lift)
    if abs(depth) <= h0 / 2:
        assert D0 == pytest.approx(depth, abs=1e-3)
    else:           # on the ramp at this point: a depth within +-h0 / 2 that gives it the same height
        assert abs(D0) == pytest.approx(h0 / 2) and np.sign(D0) == np.sign(depth)
        same = he.edit_pixel_height(height, mask, tilt_deg=tilt, elevation_deg=25.0, lift=lift, foot_depth=D0)
        assert float(same[r, c]) == pytest.approx(h, abs=1e-3)
    # a dragged height: the depth that gives it, within [-h0, h0]
    for target in (h0 * g + lift + 7.0, 0.6 * h0 * g + lift, 1.4 * h0 * g + lift):
        D = he.depth_for_height(h0, target, g, lift)
        again = he.edit_pixel_height(height, mask, tilt_deg=tilt, elevation_deg=25.0, lift=lift, foot_depth=D)
        assert float(again[r, c]) == pytest.approx(target, abs=1e-3)
    assert he.depth_for_height(h0, 10 * h0 + lift, g, lift) == pytest.approx(h0 / 2)   # at most 1.5 x as tall
    assert he.depth_for_height(h0, lift - 5.0, g, lift) == pytest.approx(-h0 / 2)     # at least half as tall


@pytest.mark.parametrize("tilt,lift", [(0.0, 0.0), (20.0, 3.0)])
def test_thickness_for_height_sets_the_lying_tops_height(tilt, lift):
    H, W = 60, 80
    m = np.zeros((H, W), bool)
    m[10:50, 10:70] = True                           # every column 40 px tall
    for target in (12.0, 30.0):
        T = he.thickness_for_height(target, he.tilt_gain(tilt, 20.0), lift)
        out = he.edit_pixel_height(np.zeros((H, W)), m, lying=True, thickness=T, tilt_deg=tilt, lift=lift)
        top = he.top_point(m, out, tilt, 20.0, lift)
        assert top[2] == pytest.approx(target, abs=1e-4)
    # dragged to the ground (or below): the flattest lying map, not thickness 0 (which
    # means the default, half the median column extent: here 20 px, a jump up)
    for target in (lift, lift - 10.0):
        T = he.thickness_for_height(target, he.tilt_gain(tilt, 20.0), lift)
        assert 0 < T <= 0.01
        out = he.edit_pixel_height(np.zeros((H, W)), m, lying=True, thickness=T, tilt_deg=tilt, lift=lift)
        assert out[m].max() <= lift + 0.01 * he.tilt_gain(tilt, 20.0) + 1e-6


def test_node_foot_depth_param_and_preview_scale(tmp_path):
    H, W = 60, 30
    _, v = grid(H, W)
    m = np.ones((H, W), np.float32)
    h = np.maximum(60.0 - v, 0).astype(np.float32)
    out = run(h, m, foot_depth=10.0)
    np.testing.assert_allclose(out[h >= 20], (h + 10.0)[h >= 20], atol=1e-4)
    from pixgraph.node import ParamError
    with pytest.raises(ParamError, match="foot_depth"):          # the engine's check, naming the param
        run(h, m, foot_depth=float("inf"))
    with pytest.raises(ValueError, match="foot_depth"):          # the function's own
        he.edit_pixel_height(h, m > 0, foot_depth=float("nan"))
    from pixgraph.session import Session
    g = tmp_path / "g.yaml"
    g.write_text("""pixgraph: 1
nodes:
  m: {type: pixgraph.InputMask}
  h: {type: pixgraph.InputPixelHeight}
  e: {type: pixgraph.PixelHeightEdit, inputs: {height: h.height, mask: m.mask}, params: {foot_depth: 12}}
outputs: {out: e.height}
""")
    s = Session()
    full = s.run(g, bind={"m": m, "h": h})["out"]
    np.testing.assert_allclose(full[h >= 24], (h + 12.0)[h >= 24], atol=1e-4)
    # a half-size preview: the depth (px) scales with the image
    h2 = np.maximum(30.0 - grid(30, 15)[1], 0).astype(np.float32)
    half = s.run(g, bind={"m": m[::2, ::2].copy(), "h": h2}, scale=0.5)["out"]
    np.testing.assert_allclose(half[h2 >= 12], (h2 + 6.0)[h2 >= 12], atol=1e-4)


def test_the_page_benchmarks_user_puts_the_body_and_top_at_their_known_heights():
    """The page benchmark's simulated user (pixgraph_lab.height.edit_plans, used by
    benchmarks/page_height_fix.py and real_photos.py): the ring and the top's square dragged
    until the body point and the top have the heights the user knows; lying, the square
    sets the thickness; outline pixels the render missed (stored height 0) are known by
    the nearest rendered pixel's height."""
    from pixgraph_lab.height import edit_plans as bench
    H, W = 100, 60
    _, v = grid(H, W)
    seen = np.zeros((H, W), bool)
    seen[20:90, 10:50] = True
    rendered = seen.copy()
    rendered[20, :] = False                          # the top row: covered by the alpha, not the render
    true_h = np.where(rendered, 1.2 * (90.0 - v), 0.0)
    known = bench.known_heights(true_h, rendered, seen)
    assert known[20, 30] == pytest.approx(true_h[21, 30]) and (known[~seen] == 0).all()
    pred = np.where(seen, 90.0 - v, 0.0)             # the contact line: right contact, 1.2x too short

    def edited(p):
        return he.edit_pixel_height(pred, seen, p.get("contact_points", []), tilt_deg=p.get("tilt", 0.0),
                                    lying=p.get("lying", False), thickness=p.get("thickness", 0.0),
                                    foot_depth=p.get("foot_depth", 0.0))
    p = bench.plan_params(["lying", "thickness"], known, seen, edited)
    top = he.top_point(seen, known)
    assert p["thickness"] == pytest.approx(top[2], abs=0.01)     # taller than the column: capped there
    assert edited(p)[int(top[1]), int(top[0])] == pytest.approx(min(top[2], 90.0 - top[1]), abs=0.01)
    for plan in (["depth"], ["top"], ["depth", "top"]):
        p = bench.plan_params(plan, known, seen, edited)
        out = edited(p)
        last = plan[-1]
        point = he.body_point(seen, known) if last == "depth" else he.top_point(seen, known)
        r, c = int(point[1]), int(point[0])
        assert out[r, c] == pytest.approx(known[r, c], abs=0.02), plan
    assert bench.plan_params(["depth"], known, seen, edited)["foot_depth"] > 0


def test_no_body_ring_where_the_body_point_is_on_the_ground():
    """A body point at height 0 before the foot depth (here a contact point set above it
    clips it to 0) has no foot depth that moves it (``depth_for_height`` gives 0 for
    any drag, wiping a saved depth): like ``top_point``, ``body_point`` is then None
    and the page draws no ring."""
    H, W = 80, 40
    _, v = grid(H, W)
    m = np.zeros((H, W), bool)
    m[10:70, 5:35] = True
    h = np.where(m, 70.0 - v, 0.0)
    edited = he.edit_pixel_height(h, m, [20.0, 20.0], foot_depth=6.0)   # contact on row 20: the middle is at 0
    assert edited[40, 20] == 0 and edited[15, 20] > 0
    assert he.body_point(m, edited, depth=6.0) is None
    ok = he.body_point(m, he.edit_pixel_height(h, m, foot_depth=6.0), depth=6.0)
    assert ok is not None and ok[3] == pytest.approx(70.0 - ok[1], abs=1e-4)
    assert he.body_point(np.zeros((H, W), bool), np.zeros((H, W))) is None


def test_foot_depth_keeps_a_contact_at_0_not_a_lifted_inputs():
    """The ramp is measured from height 0: an input already lifted off the ground
    (CutoutHeight's ``contact: lifted``) has its contact moved by the whole D; the
    node's own ``lift`` (applied after the foot depth) keeps it (module doc, step 2b)."""
    H, W = 100, 20
    _, v = grid(H, W)
    m = np.zeros((H, W), bool)
    m[10:90] = True
    grounded = np.where(m, 90.0 - v, 0.0)
    moved = he.edit_pixel_height(grounded + 30.0 * m, m, foot_depth=10.0)
    assert moved[89, 5] == pytest.approx(30.5 + 10.0)
    kept = he.edit_pixel_height(grounded, m, foot_depth=10.0, lift=30.0)
    assert kept[89, 5] == pytest.approx(30.0 + 1.5 * 0.5)
    np.testing.assert_allclose(kept[m & (grounded >= 20)], moved[m & (grounded >= 20)], atol=1e-4)


def _benchmark(name: str):
    """benchmarks/<name>.py as a module (it puts its own folder on sys.path for its imports)."""
    import importlib.util
    import pathlib
    path = pathlib.Path(__file__).parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench


def _page_height_fix():
    return _benchmark("page_height_fix")


def test_the_simulated_users_plans_moved_to_the_lab_unchanged():
    """benchmarks/page_height_fix.py uses the lab's simulated user (the same objects), and
    its params on a small synthetic cutout are the ones the benchmark's own copy gave
    before the move (numbers pinned from that code, commit 5d4b0ae): the contact points
    of 1 and 3 column bins, the lying thickness, the foot depth, the plan set's size."""
    from pixgraph_lab.height import edit_plans as ep
    bench = _page_height_fix()
    for name in ("PLANS", "NEW_PLANS", "OTHER", "plan_method", "plan_params", "true_contacts", "known_heights"):
        assert getattr(bench, name) is getattr(ep, name), name
    assert len(ep.PLANS) == 20 and set(ep.NEW_PLANS) <= set(ep.PLANS)
    assert ep.plan_method(ep.PLANS["other method + depth"], "learned") == "contact_line"
    H, W = 100, 60
    u, v = grid(H, W)
    seen = np.zeros((H, W), bool)
    seen[20:90, 10:50] = True
    seen[85:90, 10:20] = False                       # a notch: the lowest row starts at column 20
    rendered = seen.copy()
    rendered[20, :] = False
    true_h = np.where(rendered, 1.2 * (90.0 - v) + 0.1 * (u - 0.5), 0.0)
    pred = np.where(seen, 90.0 - v, 0.0)
    known = ep.known_heights(true_h, rendered, seen)
    out = {n: ep.plan_params(pl, known, seen, lambda p: ep.edit_with(pred, seen, p)) for n, pl in ep.PLANS.items()}
    assert out["1 contact"] == {"contact_points": [20.5, 89.5]}
    assert out["3 contacts"] == {"contact_points": [20.5, 89.5, 24.5, 89.5, 37.5, 89.5]}
    assert out["2 contacts, upright"] == {"contact_points": [20.5, 89.5, 30.5, 89.5], "contact_mode": "upright"}
    assert out["lying + thickness"] == {"lying": True, "thickness": pytest.approx(85.2)}
    assert out["depth"] == {"foot_depth": pytest.approx(10.1)}
    assert out["1 contact + depth + top"]["foot_depth"] == pytest.approx(10.6)
    assert out["other method"] == {}


def test_true_contacts_options_give_real_photos_old_plans():
    """``true_contacts`` also makes real_photos.py's old plans' points (which had a near-copy
    of it): with no pixel below 1 px it falls back to the mask's lowest ``fallback_rows``
    rows, and ``v_at`` puts the point on the pixel's bottom edge. Analytic: a mask whose
    lowest row is 79 for columns 10-19 and 78 for columns 20-49, heights never below 1 px."""
    from pixgraph_lab.height.edit_plans import true_contacts
    mask = np.zeros((100, 60), bool)
    mask[20:79, 10:50] = True
    mask[79, 10:20] = True
    mask[60:75, 50:55] = True                       # an arm: lowest in its own column bin, rows 60-74
    true_h = np.where(mask, 5.0, 0.0)
    # the whole mask: the lowest pixel of each third of columns 10-54
    assert true_contacts(true_h, mask, 3) == [(10.5, 79.5), (25.5, 78.5), (40.5, 78.5)]
    # the two lowest rows only (78, 79): the arm's columns drop out, bins of columns 10-49
    assert true_contacts(true_h, mask, 3, fallback_rows=2) == [(10.5, 79.5), (24.5, 78.5), (37.5, 78.5)]
    assert true_contacts(true_h, mask, 3, fallback_rows=1, v_at=1.0) == [(10.5, 80.0), (14.5, 80.0),
                                                                         (17.5, 80.0)]
    # a foot pixel (true height < 1 px) wins over everything else, whatever the options
    true_h[50, 30] = 0.5
    assert true_contacts(true_h, mask, 3, fallback_rows=2, v_at=1.0) == [(30.5, 51.0)]


def test_the_residual_benchmark_splits_a_known_residual_into_columns_rows_and_bulge():
    """benchmarks/page_height_residual.py's numbers on maps whose difference is known: a
    per-column offset is all in the column means (and its exact column fix is the truth),
    a per-row one all in the row means, a bulge across each row all in the bulge share
    with the slope it was made with."""
    res = _benchmark("page_height_residual")
    H, W = 60, 50
    u, v = grid(H, W)
    m = np.zeros((H, W), bool)
    m[10:50, 10:40] = True
    t = np.where(m, 50.0 - v, 0.0)
    col = np.where(m, t - 0.3 * (u - 10.0), 0.0)                    # a part whose ground is elsewhere
    s = res.residual_stats(col, t, m)
    assert s["cols"] == pytest.approx(1.0) and s["rows"] == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(s["col_fix"][m], t[m], atol=1e-9)
    assert s["bias"] == pytest.approx(0.3 * 15.0) and s["k"] > 1
    row = np.where(m, t - 0.1 * (50.0 - v), 0.0)                    # heights 10 % short: a row profile
    s = res.residual_stats(row, t, m)
    assert s["rows"] == pytest.approx(1.0) and s["cols"] == pytest.approx(0.0, abs=1e-9)
    assert s["k"] == pytest.approx(1 / 0.9) and s["up"][2] > s["up"][0] > 0
    # a rounded front: 0.2 x the row's half-width x sqrt(1 - t^2) missing (the edit too flat)
    w = 15.0
    bump = 0.2 * w * np.sqrt(np.clip(1 - ((u - 25.0) / w) ** 2, 0, 1))
    s = res.residual_stats(np.where(m, t - bump, 0.0), t, m)
    assert s["bulge"] == pytest.approx(1.0, abs=1e-9) and s["beta"] == pytest.approx(0.2, abs=1e-9)
    assert s["across"][0] > s["across"][1] > s["across"][2]


def test_the_user_who_watches_the_shadow_chooses_among_the_rules_handle_heights():
    """User B (docs/height-record.md, "Rules fixed before measuring: a user who watches the
    shadow"): each drag is offered user A's height and the rule's fixed set (the top at h0
    x 0.4..1.6, the ring at h0 + bh x -0.3..0.3, the lying thickness at bh x 0.05..1.0),
    the watcher's choice is applied, and ``targets`` records the height it ended at."""
    from pixgraph_lab.height import edit_plans as ep
    H, W = 100, 60
    _, v = grid(H, W)
    seen = np.zeros((H, W), bool)
    seen[20:90, 10:50] = True
    true_h = np.where(seen, 1.25 * (90.0 - v), 0.0)   # 1.25: off the rule's grid
    pred = np.where(seen, 90.0 - v, 0.0)

    def edited(p):
        return ep.edit_with(pred, seen, p)
    assert ep.box_height(seen) == 70.0
    offered = []

    def first(cands):                                 # keeps user A's height: the same params as A
        offered.append(cands)
        return 0
    for plan in (["top"], ["depth"], ["lying", "thickness"], ["depth", "top"]):
        assert ep.plan_params(plan, true_h, seen, edited, watch=first) == ep.plan_params(plan, true_h, seen, edited)
    top0 = he.top_point(seen, edited({}))
    assert len(offered[0]) == 1 + len(ep.WATCH_TOP)   # A's tilt first, then the grid's 13
    assert len(offered[2]) == 1 + len(ep.WATCH_THICKNESS)
    body0 = he.body_point(seen, edited({}))
    want = 0.8 * top0[2]                              # a watcher who likes the top at 0.8 of its height

    def likes(key, target, point):
        def pick(cands):
            hs = [point(edited(c))[2] for c in cands]
            return int(np.argmin([abs(h - target) for h in hs]))
        return pick
    targets = {}
    p = ep.plan_params(["top"], true_h, seen, edited, watch=likes("tilt", want, lambda e: he.top_point(seen, e)),
                       targets=targets)
    assert targets["tilt"] == pytest.approx(want)
    assert he.top_point(seen, edited(p))[2] == pytest.approx(want, abs=0.05)
    want = body0[2] - 0.25 * 70.0                     # the ring a quarter box height lower
    targets = {}
    p = ep.plan_params(["depth"], true_h, seen, edited, watch=likes("foot_depth", want,
                                                                    lambda e: he.body_point(seen, e)),
                       targets=targets)
    assert targets["foot_depth"] == pytest.approx(want)
    assert he.body_point(seen, edited(p))[2] == pytest.approx(max(want, body0[2] / 2), abs=0.05)
