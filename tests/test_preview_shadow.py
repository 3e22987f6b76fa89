"""pixgraph.PreviewShadow, the soft shadows' preview stand-in (nodes/ops/preview_shadow.py):
its kernel against the numpy reference, the penumbra estimate's guarantees and an
analytic ramp, and the served preview graph that uses it and follows the light's radius."""
import math

import numpy as np
import pytest
from scipy import ndimage

from pixgraph_nodes.ops import preview_shadow as P
from pixgraph_nodes.ops import shadow as S
from pixgraph_serve.state import ServeState

from _shadow_scenes import blobs, figure, wall_bg
from serve_helpers import copy_scene

LIGHTS = [(30.0, -40.0, 150.0, 1.0),     # in front, up left: the shadow falls back and down right
          (110.0, 20.0, 60.0, 1.0),      # low, to the right
          (60.0, 300.0, -50.0, -1.0),    # behind the camera plane
          (0.4, 0.1, 0.6, 0.0)]          # at infinity, parallel to the image plane


@pytest.mark.parametrize("light", LIGHTS)
def test_kernel_matches_the_reference(device, light):
    mask, fg, bg = figure(72, 96)
    dark, dist = P.hard_shadow_distance(device, mask, fg, bg, light, 2.0)
    dark_ref, dist_ref = P.hard_shadow_distance_ref(mask, fg, bg, light, 2.0)
    assert dark_ref.sum() > 50                                   # a real shadow
    np.testing.assert_array_equal(dark, dark_ref)
    np.testing.assert_allclose(dist, dist_ref, rtol=1e-5, atol=1e-3)
    # the darkness is the hard shadow's; the distance is zero exactly where lit
    np.testing.assert_array_equal(dark, 1.0 - S.hard_shadow_ref(mask, fg, bg, light, 2.0))
    assert np.all((dist > 0) == (dark > 0))


def test_kernel_bands_change_nothing(device):
    mask, fg = blobs(64, 80, 3)
    bg = wall_bg(64, 80, 20)
    scene = P.PreviewScene(device, mask, fg, bg, 1.5)
    one = scene.hard_shadow_distance(LIGHTS[0])
    calls = []
    banded = scene.hard_shadow_distance(LIGHTS[0], progress=lambda f, m: calls.append(f))
    assert calls and calls[-1] == 1.0
    np.testing.assert_array_equal(one[0], banded[0])
    np.testing.assert_array_equal(one[1], banded[1])


def test_straight_edge_becomes_the_box_ramp():
    """A shadow filling the left half, every blocker 50 px away, softness 0.1: the box
    half-size is 5 px, so across the edge the darkness is the fraction of the 11
    columns around each pixel that are in shadow, a linear ramp 11 px wide."""
    H, W, edge = 40, 60, 30
    dark = np.zeros((H, W), np.float32)
    dark[:, :edge] = 1.0
    dist = np.where(dark > 0, 50.0, 0.0).astype(np.float32)
    out = P.penumbra_blur(dark, dist, np.zeros((H, W), bool), 0.1)
    cols = np.arange(W)
    want = np.clip((edge - (cols - 5)) / 11.0, 0.0, 1.0)
    np.testing.assert_allclose(out, np.broadcast_to(want, (H, W)), atol=1e-6)
    assert out[0, edge - 1] == pytest.approx(6 / 11) and out[0, edge] == pytest.approx(5 / 11)


def test_a_point_light_keeps_the_hard_shadow_and_the_umbra_core():
    mask, fg, bg = figure(96, 128)
    dark, dist = P.hard_shadow_distance_ref(mask, fg, bg, LIGHTS[0], 2.0)
    inside = mask > 0.5
    np.testing.assert_array_equal(P.penumbra_blur(dark, dist, inside, 0.0), dark)
    soft = 0.04
    out = P.penumbra_blur(dark, dist, inside, soft)
    assert out.dtype == np.float32 and out.min() >= 0.0 and out.max() <= 1.0
    assert ((out > 0.02) & (out < 0.98)).sum() > 100             # a penumbra appeared
    reach = math.ceil(soft * dist[dark > 0].max())
    box = np.ones((2 * reach + 1, 2 * reach + 1), bool)
    for side, least in ((~inside, 50), (inside, 0)):      # the cutout's self-shadow is thin here
        # the umbra's core: every same-side pixel within reach shadowed -> still 1
        lit_near = ndimage.binary_dilation(side & (dark == 0), box)
        core = side & (dark == 1) & ~lit_near
        assert core.sum() >= least
        np.testing.assert_array_equal(out[core], 1.0)
        # no same-side shadow within reach -> still 0: the shadow spreads at most `reach`
        far = side & ~ndimage.binary_dilation(side & (dark > 0), box)
        np.testing.assert_array_equal(out[far], 0.0)


def test_the_two_sides_of_the_outline_do_not_mix():
    """The cutout (inside) is lit and the background beside it shadowed: the cutout's
    pixels average only cutout pixels, so they stay lit, and the background's edge pixels
    only background pixels, so they stay dark."""
    H, W = 30, 40
    inside = np.zeros((H, W), bool)
    inside[:, 20:] = True
    dark = np.where(inside, 0.0, 1.0).astype(np.float32)
    dark[:, :5] = 0.0                      # a lit strip far left: the background has an edge
    dist = np.where(dark > 0, 40.0, 0.0).astype(np.float32)
    out = P.penumbra_blur(dark, dist, inside, 0.1)
    np.testing.assert_array_equal(out[:, 20:], 0.0)
    np.testing.assert_array_equal(out[:, 10:20], 1.0)
    assert 0.0 < out[0, 5] < 1.0                   # while the background's own edge softened


def test_bad_inputs_are_refused():
    z = np.zeros((4, 4), np.float32)
    with pytest.raises(ValueError, match="softness"):
        P.penumbra_blur(z, z, z > 0, -1.0)
    with pytest.raises(ValueError, match="shape"):
        P.penumbra_blur(z, np.zeros((3, 4)), z > 0, 0.1)


# -- the stretched penumbra (penumbra_blur's geometry; a benchmark candidate) -------------------

def _ellipse_axes(a1, a2):
    """major, minor half-axes and the major's unit direction of {x a1 + y a2: x^2 + y^2 <= 1}."""
    U, sv, _ = np.linalg.svd(np.column_stack([a1, a2]))
    return sv[0], sv[1], U[:, 0]


@pytest.mark.parametrize("receiver, controls", [
    ("ground", (10.0, 20.0)), ("ground", (60.0, 15.0)), ("ground", (170.0, 25.0)),
    # (light 170 deg round is behind the wall: it lights only the wall's back)
    ("wall", (10.0, 20.0)), ("wall", (60.0, 15.0)), ("wall", (-45.0, 35.0))])
def test_penumbra_axes_match_the_3d_construction(receiver, controls):
    """The ellipse penumbra_axes finds in pixel-height space equals the one built in 3D:
    the rays from the disk's 4 extreme points through a blocker point meet the receiver
    plane (the ground Y = 0, or a wall Z = -5 facing the camera, whose pixel height
    falls one px per image row: slope dh/dv = -1) at 4 points; their image offsets from
    the centre's shadow give the two conjugate half-axes."""
    from pixgraph_nodes.ops import lights as L
    from pixgraph_nodes.ops.camera import Camera

    cam = Camera(512, 512, hfov=50.0, horizon=120.0, cam_height=1.0)
    target = np.array([0.0, 0.0, -3.0])
    light = L.from_controls(target, controls[0], controls[1], 3.0, radius=0.3)
    top = np.array([0.05, 0.6, -3.0])                        # the blocker (a pole's top)
    normal, offset = (np.array([0.0, 1.0, 0.0]), 0.0) if receiver == "ground" else (np.array([0.0, 0.0, 1.0]), -5.0)

    def cast(E):                                             # ray E -> top onto the plane n.X = offset
        d = top - E
        return top + (offset - normal @ top) / (normal @ d) * d

    C = np.asarray(light.position)
    S0 = cast(C)
    r, _ = cam.project(S0)
    off = [cam.project(cast(E))[0][:2] - r[:2] for E in L.extreme_points_3d(light)]
    want = _ellipse_axes((off[0] - off[1]) / 2, (off[2] - off[3]) / 2)
    b, _ = cam.project(top)
    blocker = np.linalg.norm(b - r)                          # distance in (u, v, h) pixels
    slope_v = 0.0 if receiver == "ground" else -1.0
    if receiver == "wall":      # the wall's pixel height really falls one px per row
        r2, _ = cam.project(S0 + np.array([0.0, 0.1, 0.0]))
        assert (r2[2] - r[2]) / (r2[1] - r[1]) == pytest.approx(-1.0)
    major, minor, cu, cv = P.penumbra_axes(np.array([r[0]]), np.array([r[1]]), np.array([r[2]]),
                                           np.zeros(1), np.array([slope_v]), np.array([blocker]),
                                           L.light_point(light, cam), L.disk_extremes(light, cam))
    assert want[0] > 2.0                                      # a real penumbra, in px
    assert major[0] == pytest.approx(want[0], rel=2e-3, abs=2e-3)
    assert minor[0] == pytest.approx(want[1], rel=2e-3, abs=2e-3)
    assert abs(cu[0] * want[2][0] + cv[0] * want[2][1]) == pytest.approx(1.0, abs=1e-3)


def _pole_lights():
    from pixgraph_nodes.ops import lights as L
    from test_geometry_shadows import FOOT
    return {"low front": L.from_controls(FOOT, 10.0, 20.0, 3.0, radius=0.3),
            "behind": L.from_controls(FOOT, 170.0, 25.0, 3.0, radius=0.3)}


@pytest.mark.parametrize("name", ["low front", "behind"])
def test_stretched_penumbra_of_a_pole_on_the_ground(device, name):
    """A thin upright pole on flat ground under a low disk light: its long shadow's
    penumbra is stretched along the shadow (the ellipse's axes differ by more than 1.5x),
    and the stretched estimate is nearer SoftShadow with 256 samples than the square box
    (RMSE ratio measured 0.41 and 0.63; asserted < 0.75)."""
    from pixgraph_nodes.ops import lights as L
    from pixgraph_nodes.ops.softness import softness_of
    from test_geometry_shadows import CAM, pole

    light = _pole_lights()[name]
    mask, fg = pole()
    bg = np.zeros_like(fg)
    lc, ex = L.light_point(light, CAM), L.disk_extremes(light, CAM)
    ref = 1.0 - S.soft_shadow(device, mask, fg, bg, L.disk_samples(light, CAM, 256, 0), 1.0)
    dark, dist = P.hard_shadow_distance(device, mask, fg, bg, lc, 1.0)
    soft = softness_of(light, CAM, mask, fg)
    square = P.penumbra_blur(dark, dist, mask > 0.5, soft)
    stretched = P.penumbra_blur(dark, dist, mask > 0.5, soft, (bg, lc, ex))
    i, j = np.nonzero((dark > 0) & (mask <= 0.5))
    major, minor, _, _ = P.penumbra_axes(j + 0.5, i + 0.5, bg[i, j], 0 * bg[i, j], 0 * bg[i, j], dist[i, j], lc, ex)
    assert np.median(major / minor) > 1.5
    assert stretched.min() >= 0.0 and stretched.max() <= 1.0
    assert rmse(stretched, ref) < 0.75 * rmse(square, ref), (rmse(stretched, ref), rmse(square, ref))
    assert rmse(square, ref) < rmse(dark, ref)


@pytest.mark.parametrize("light", LIGHTS)
def test_stretched_penumbra_keeps_the_guarantees(light):
    """With a geometry (any light: behind the camera plane, at infinity): softness 0 (a
    point light) gives the hard shadow exactly; the darkness stays finite in [0, 1]; the
    umbra's core stays 1 and no shadow spreads farther than step 1's reach (softness x
    max d), though the boxes are longer; a bad geometry is refused."""
    mask, fg, bg = figure(96, 128)
    light = np.array(light, np.float32)
    dark, dist = P.hard_shadow_distance_ref(mask, fg, bg, light, 2.0)
    inside = mask > 0.5
    ext = np.array([light + (6, 0, 0, 0), light - (6, 0, 0, 0), light + (0, 0, 6, 0), light - (0, 0, 6, 0)],
                   np.float32)
    np.testing.assert_array_equal(P.penumbra_blur(dark, dist, inside, 0.0, (bg, light, ext)), dark)
    soft = 0.04
    out = P.penumbra_blur(dark, dist, inside, soft, (bg, light, ext))
    assert out.dtype == np.float32 and out.min() >= 0.0 and out.max() <= 1.0
    assert ((out > 0.02) & (out < 0.98)).sum() > 50              # a penumbra appeared
    assert np.abs(out - P.penumbra_blur(dark, dist, inside, soft)).max() > 0.05    # it does differ
    reach = math.ceil(soft * dist[dark > 0].max())
    box = np.ones((2 * reach + 1, 2 * reach + 1), bool)
    side = ~inside
    core = side & (dark == 1) & ~ndimage.binary_dilation(side & (dark == 0), box)
    far = side & ~ndimage.binary_dilation(side & (dark > 0), box)
    assert core.sum() + far.sum() > 1000
    np.testing.assert_array_equal(out[core], 1.0)
    np.testing.assert_array_equal(out[far], 0.0)
    with pytest.raises(ValueError, match="bg_height"):
        P.penumbra_blur(dark, dist, inside, soft, (bg[:10], light, ext))



def _kernel_scenes():
    """(name, mask, fg, bg, light point, extremes, softness, thickness): the figure against
    a wall (the lights of LIGHTS: in front, low, behind the camera plane, at infinity), blobs
    on a wall, and the thin pole's long ground shadows under a low light in front and behind
    and under two suns (lights at infinity; softness None: the light's own)."""
    from pixgraph_nodes.ops import lights as L
    from test_geometry_shadows import CAM, pole

    out = []
    mask, fg, bg = figure(96, 128)
    for k, light in enumerate(LIGHTS):
        lp = np.array(light, np.float32)
        d = 4.0 + 3.0 * k                                  # disks of several sizes and orientations
        ext = np.array([lp + (d, 0, 0, 0), lp - (d, 0, 0, 0), lp + (0, 0.5 * d, d, 0), lp - (0, 0.5 * d, d, 0)],
                       np.float32)
        out.append((f"figure {k}", mask, fg, bg, lp, ext, 0.03 + 0.01 * k, 2.0))
    mask, fg = blobs(80, 112, 4)
    bg = wall_bg(80, 112, 30)
    lp = np.array(LIGHTS[1], np.float32)
    out.append(("blobs on a wall", mask, fg, bg, lp, np.array([lp + (5, 0, 0, 0), lp - (5, 0, 0, 0),
                                                               lp + (0, 0, 5, 0), lp - (0, 0, 5, 0)], np.float32),
                0.06, 1.5))
    mask, fg = pole()
    suns = {"sun": L.directional_light((0.4, 1.0, 0.5), angular_radius_deg=3.0),
            "low sun": L.directional_light((-1.0, 0.3, 0.2), angular_radius_deg=2.0)}
    for name, light in {**_pole_lights(), **suns}.items():
        out.append((f"pole {name}", mask, fg, np.zeros_like(fg), L.light_point(light, CAM),
                    L.disk_extremes(light, CAM), light, 1.0))
    return out


def test_swept_boxes_kernel_matches_the_reference(device):
    """The stretched boxes summed by the OpenCL kernel ``swept_boxes`` (penumbra_blur with a
    device) equal the numpy reference ``_swept_boxes`` to float rounding on walls and long
    ground shadows, lights in front, low, behind the camera plane and at infinity (9
    scenes; on the benchmark's 62 they are equal bit for bit); the
    stretched path is really taken (it differs from the square box in many pixels)."""
    from pixgraph_nodes.ops.softness import softness_of
    from test_geometry_shadows import CAM

    if not P._has_doubles(device):
        pytest.skip("the device has no doubles: penumbra_blur sums the boxes in numpy")
    calls = []
    orig = P._swept_boxes_cl

    def counted(*a, **k):
        calls.append(a[1].size)
        return orig(*a, **k)

    for name, mask, fg, bg, lp, ext, soft, thick in _kernel_scenes():
        if not isinstance(soft, float):          # a light: its own softness
            soft = softness_of(soft, CAM, mask, fg)
        dark, dist = P.hard_shadow_distance_ref(mask, fg, bg, lp, thick)
        inside = mask > 0.5
        ref = P.penumbra_blur(dark, dist, inside, soft, (bg, lp, ext))
        P._swept_boxes_cl = counted
        try:
            got = P.penumbra_blur(dark, dist, inside, soft, (bg, lp, ext), device=device)
        finally:
            P._swept_boxes_cl = orig
        assert calls and calls[-1] > 30, name                    # the kernel ran on the mixed pixels
        square = P.penumbra_blur(dark, dist, inside, soft)
        assert (np.abs(ref - square) > 0.02).sum() > 20, name    # the stretched boxes changed pixels
        assert got.dtype == np.float32
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-6, err_msg=name)
    # a point light: the hard shadow, with or without the device
    np.testing.assert_array_equal(P.penumbra_blur(dark, dist, inside, 0.0, (bg, lp, ext), device=device), dark)


# -- SSN++'s thickness in the preview (its window's pixels, not the image's) ----------------------

def _tall_figure_scene():
    """The figure, 1.6x, on a 512 x 512 image under CAM: about 430 px tall, so SSN++'s
    window brings it to the trained 120 px at a scale of about 0.28 network px per image px."""
    from pixgraph_nodes.ops import lights as L
    from test_geometry_shadows import CAM

    mask, fg, bg = figure(512, 512, scale=1.6)
    light = L.from_controls((0.0, 0.0, -3.0), 30.0, 35.0, 3.0, radius=0.4)
    return mask, fg, bg, light, CAM


def _preview_node(device, mask, fg, bg, light, cam, scale=1.0, **params):
    from pixgraph.node import Namespace
    from pixgraph_nodes.preview_shadow import PreviewShadow
    from test_geometry_shadows import Ctx

    ins = Namespace({"mask": mask, "fg_height": fg, "bg_height": bg, "light": light, "camera": cam})
    return PreviewShadow().compute(Ctx(device, scale), ins,
                                   Namespace(PreviewShadow.spec.coerce_params(params)))["darkness"]


def test_ssn_thickness_is_read_in_the_windows_pixels(device):
    """PreviewShadow with ``method: ssn`` (what SoftShadowSSN's stand-in gets) reads
    ``thickness`` as SSN++ does, in pixels of the network's window: the image's
    thickness is it divided by the window's scale, here 120 px (the trained object
    height) over the cutout's 430-odd rows, about 0.28: 4 window px are about 14 image
    px. Read as image px (any other method), the shadow differs in hundreds of pixels."""
    from pixgraph_nodes.ops.lights import light_point
    from pixgraph_nodes.ops.softness import softness_of

    mask, fg, bg, light, cam = _tall_figure_scene()
    rows = np.flatnonzero((mask > 0.5).any(axis=1))
    k = 120.0 / (rows[-1] - rows[0] + 1)
    assert 0.2 < k < 0.35
    soft = softness_of(light, cam, mask, fg)
    want = P.preview_soft_shadow(device, mask, fg, bg, light_point(light, cam), soft, 4.0 / k)
    unmapped = P.preview_soft_shadow(device, mask, fg, bg, light_point(light, cam), soft, 4.0)
    got = _preview_node(device, mask, fg, bg, light, cam, method="ssn", thickness=4.0)
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(_preview_node(device, mask, fg, bg, light, cam, method="soft", thickness=4.0),
                                  unmapped)
    # a scaled run (the page's previews) hands the node 4 x 0.5 (thickness is declared in image px): with
    # method ssn the node divides the run's scale back out, since the window's pixels do not scale
    np.testing.assert_array_equal(_preview_node(device, mask, fg, bg, light, cam, scale=0.5, method="ssn",
                                                thickness=2.0), want)
    assert (np.abs(want - unmapped) > 0.1).sum() > 300, int((np.abs(want - unmapped) > 0.1).sum())


def test_a_scaled_run_leaves_ssns_thickness_in_window_pixels():
    """Window pixels do not change with the run's working resolution: a scaled run
    multiplies SoftShadow's thickness (image px) by the scale, not SoftShadowSSN's, and
    keys PreviewShadow by the scale (it divides the scale back out for method ssn)."""
    from pixgraph.resolve import scale_params
    from pixgraph_nodes.preview_shadow import PreviewShadow
    from pixgraph_nodes.soft_shadow import SoftShadow
    from pixgraph_nodes.ssn_soft_shadow import SoftShadowSSN

    got = {}
    for cls in (SoftShadow, SoftShadowSSN, PreviewShadow):
        params, key = {"thickness": 4.0}, {"thickness": 4.0}
        scale_params(cls.spec, params, key, 0.25)
        got[cls.__name__] = (params["thickness"], key.get("@scale"))
    assert got == {"SoftShadow": (1.0, None), "SoftShadowSSN": (4.0, None), "PreviewShadow": (1.0, 0.25)}


def test_a_shadow_forced_to_ssn_in_a_scaled_run_is_ssns(device):
    """``pixgraph.Shadow`` with ``method: ssn`` in a run at half the resolution (its
    thickness, declared in image px, reaches it halved) gives exactly SoftShadowSSN's
    shadow with the unscaled thickness: both read it in the window's pixels."""
    pytest.importorskip("torch")
    from pixgraph.node import Namespace
    from pixgraph_nodes.shadow import Shadow
    from pixgraph_nodes.ssn_soft_shadow import SoftShadowSSN
    from test_geometry_shadows import Ctx

    mask, fg, bg, light, cam = _tall_figure_scene()
    ins = Namespace({"mask": mask, "fg_height": fg, "bg_height": bg, "light": light, "camera": cam})

    def run(cls, scale, **params):
        return cls().compute(Ctx(device, scale), ins, Namespace(cls.spec.coerce_params(params)))["darkness"]
    ssn = run(SoftShadowSSN, 0.5, thickness=6.0)
    np.testing.assert_array_equal(run(Shadow, 0.5, method="ssn", thickness=3.0), ssn)
    assert np.abs(run(SoftShadowSSN, 0.5, thickness=3.0) - ssn).max() > 0.01   # the thickness matters here


@pytest.mark.parametrize("object_px", [30, 64, 100, 121, 430, 900])
def test_window_scale_is_the_scale_ssn_crop_chooses(object_px):
    """softness.window_scale (torch-free, for the preview) is the scale SSN++'s own window
    choice (ssn_crop.choose_window) gives when the shadow's extent is the cutout's
    (within its rounding to whole pixels)."""
    pytest.importorskip("torch")
    from pixgraph_nodes.ops import ssn_crop
    from pixgraph_nodes.ops.softness import window_scale

    H, W = 1000, 800
    mask = np.zeros((H, W), np.float32)
    mask[50:50 + object_px, 300:340] = 1.0
    win = ssn_crop.choose_window(H, W, (300, 50, 340, 50 + object_px), float(object_px))
    assert window_scale(mask) == pytest.approx(win.ky, rel=0.01)
    assert window_scale(np.zeros((4, 4), np.float32)) == 1.0


def test_the_preview_swap_tells_the_stand_in_ssns_unit(state):
    """The served preview of SoftShadowSSN is PreviewShadow with its thickness and
    ``method: ssn`` (SoftShadowSSN's ``preview_params``); SoftShadow's keeps only the
    shared params (its thickness is in image pixels)."""
    pytest.importorskip("torch")
    assert state.preview_graph().nodes["shadow"].params.get("method") is None
    state.set_type("shadow", "pixgraph.SoftShadowSSN")
    try:
        state.set_params({"shadow.thickness": 5})
        prev = state.preview_graph().nodes["shadow"]
        assert prev.type == "pixgraph.PreviewShadow"
        assert dict(prev.params) == {"thickness": 5, "method": "ssn"}
    finally:
        state.set_type("shadow", "pixgraph.SoftShadow")


@pytest.fixture(scope="module")
def state(tmp_path_factory):
    return ServeState(copy_scene(str(tmp_path_factory.mktemp("preview"))))


def rmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def test_served_previews_follow_the_light_radius(state):
    """The page's previews (ServeState.preview_graph) use PreviewShadow: a point light
    gives exactly the hard shadow, a larger radius a wider penumbra, and the preview is
    nearer the final SoftShadow than the hard shadow is (work 0.5, as the page's drags)."""
    prev = state.preview_graph()
    assert prev.nodes["shadow"].type == "pixgraph.PreviewShadow"
    assert dict(prev.nodes["shadow"].params) == {"thickness": 6}      # SoftShadow's samples dropped

    def darkness(mode, radius, hard=False):
        state.set_params({"light.radius": radius})
        if hard:
            state.set_type("shadow", "pixgraph.HardShadow")
        try:
            return state.run(["shadow.darkness"], mode, scale=0.5)["shadow.darkness"]
        finally:
            if hard:
                state.set_type("shadow", "pixgraph.SoftShadow")

    np.testing.assert_array_equal(darkness("preview", 0.0), darkness("final", 0.0, hard=True))
    hard = darkness("final", 0.25, hard=True)
    small, large = darkness("preview", 0.25), darkness("preview", 0.5)
    penumbra = [int(((d > 0.02) & (d < 0.98)).sum()) for d in (hard, small, large)]
    assert penumbra[0] == 0 and 0 < penumbra[1] < penumbra[2], penumbra
    final = darkness("final", 0.25)
    assert rmse(small, final) < 0.6 * rmse(hard, final), (rmse(small, final), rmse(hard, final))


def test_a_shadow_forced_hard_previews_hard(state):
    """pixgraph.Shadow's ``method`` is one of the params PreviewShadow shares: forced
    ``hard``, its preview is the hard shadow too (``soft``: the estimate)."""
    state.set_params({"light.radius": 0.25})
    state.set_type("shadow", "pixgraph.Shadow")
    try:
        state.set_params({"shadow.method": "hard"})
        assert state.preview_graph().nodes["shadow"].params["method"] == "hard"
        hard_prev = state.run(["shadow.darkness"], "preview", scale=0.5)["shadow.darkness"]
        hard = state.run(["shadow.darkness"], scale=0.5)["shadow.darkness"]
        state.set_params({"shadow.method": "soft"})
        soft_prev = state.run(["shadow.darkness"], "preview", scale=0.5)["shadow.darkness"]
    finally:
        state.set_type("shadow", "pixgraph.SoftShadow")
    np.testing.assert_array_equal(hard_prev, hard)
    assert set(np.unique(hard_prev)) == {0.0, 1.0}
    assert ((soft_prev > 0.02) & (soft_prev < 0.98)).sum() > 100


# -- in the page (headless Chromium) ------------------------------------------------------------

def test_the_page_preview_changes_with_the_softness_slider(tmp_path):
    """Dragging the toolbar's softness slider (the light's radius): the previews drawn while
    the pointer is down differ from one radius to the next (with HardShadow as the stand-in
    they are the same image: 0 pixels differ)."""
    from serve_helpers import chromium_browser, running_server
    from test_page_photo import open_page, own_photo_copy, shown

    graph = own_photo_copy(str(tmp_path / "served"))
    with chromium_browser() as browser, running_server(graph) as (url, _):
        page, errors = open_page(browser, url)
        box = page.locator("#softness").bounding_box()
        y = box["y"] + box["height"] / 2

        def x(value):                            # the slider spans 0 .. 1.5
            return box["x"] + 8 + (box["width"] - 16) * value / 1.5

        def preview_at(value):
            seq = page.evaluate("(window.pixgraphShown.at(-1) || {seq: 0}).seq")
            page.mouse.move(x(value), y, steps=4)
            page.wait_for_function(
                f"() => {{ const l = window.pixgraphShown.at(-1); return l && l.mode === 'preview' && l.seq > {seq}"
                f" && Number(document.getElementById('softness').value) > {value - 0.1}"
                f" && Number(document.getElementById('softness').value) < {value + 0.1}; }}", timeout=120000)
            # the newest edit's preview, not one in flight before it: wait for the page's queue
            page.wait_for_function("(q => !q.inflight && !q.pending)(window.pixgraphQueue())", timeout=120000)
            return shown(page), float(page.evaluate("document.getElementById('softness').value"))

        page.mouse.move(x(0.3), y)
        page.mouse.down()
        small, v_small = preview_at(0.1)
        large, v_large = preview_at(1.2)
        page.mouse.up()
        assert v_large > v_small + 0.8, (v_small, v_large)
        assert small.shape == large.shape
        diff = np.abs(small - large).max(axis=2)
        assert (diff > 0.03).sum() > 200, int((diff > 0.03).sum())
        assert not errors, errors
        page.close()


# -- the node ---------------------------------------------------------------------------------

def test_node_on_a_pole_under_the_sun(device):
    """pixgraph.PreviewShadow on the thin pole of test_geometry_shadows under a directional
    light: a point sun gives HardShadow's darkness exactly, a wider sun a wider penumbra
    (more pixels between 0.02 and 0.98); an empty mask casts nothing."""
    from pixgraph.node import Namespace
    from pixgraph_nodes.hard_shadow import HardShadow
    from pixgraph_nodes.ops import lights as L
    from pixgraph_nodes.preview_shadow import PreviewShadow
    from test_geometry_shadows import CAM, Ctx, pole

    mask, fg = pole()
    bg = np.zeros_like(fg)

    def run(cls, mask, sun_deg):
        light = L.directional_light((0.4, 1.0, 0.5), angular_radius_deg=sun_deg)
        ins = Namespace({"mask": mask, "fg_height": fg, "bg_height": bg, "light": light, "camera": CAM})
        out = cls().compute(Ctx(device), ins, Namespace(cls.spec.coerce_params({})))
        np.testing.assert_allclose(out["lit"], 1.0 - out["darkness"])
        return out["darkness"]

    hard = run(HardShadow, mask, 0.0)
    assert hard.sum() > 100
    np.testing.assert_array_equal(run(PreviewShadow, mask, 0.0), hard)
    penumbra = []
    for deg in (1.0, 3.0):
        d = run(PreviewShadow, mask, deg)
        assert d.min() >= 0.0 and d.max() <= 1.0
        penumbra.append(int(((d > 0.02) & (d < 0.98)).sum()))
    assert 0 < penumbra[0] < penumbra[1], penumbra
    np.testing.assert_array_equal(run(PreviewShadow, np.zeros_like(mask), 3.0), 0.0)


@pytest.mark.parametrize("name", ["low front", "behind"])
def test_node_keeps_the_square_box(device, name):
    """pixgraph.PreviewShadow (version 5) gives the square box's estimate, not the stretched
    one (version 4, left out: docs/server.md): on the pole's long ground shadow under a low
    disk light its darkness is penumbra_blur's without a geometry, and differs from the
    stretched one; the same light shrunk to a point gives HardShadow's darkness exactly."""
    from pixgraph.node import Namespace
    from pixgraph_nodes.hard_shadow import HardShadow
    from pixgraph_nodes.ops import lights as L
    from pixgraph_nodes.ops.softness import softness_of
    from test_geometry_shadows import CAM, Ctx, pole

    mask, fg = pole()
    bg = np.zeros_like(fg)
    light = _pole_lights()[name]
    got = _preview_node(device, mask, fg, bg, light, CAM)
    lc, ex = L.light_point(light, CAM), L.disk_extremes(light, CAM)
    dark, dist = P.hard_shadow_distance(device, mask, fg, bg, lc, 1.0)
    soft = softness_of(light, CAM, mask, fg)
    stretched = P.penumbra_blur(dark, dist, mask > 0.5, soft, (bg, lc, ex))
    square = P.penumbra_blur(dark, dist, mask > 0.5, soft)
    np.testing.assert_array_equal(got, square)
    assert (np.abs(got - stretched) > 0.05).sum() > 100
    point = L.disk_light(light.position, radius=0.0)
    ins = Namespace({"mask": mask, "fg_height": fg, "bg_height": bg, "light": point, "camera": CAM})
    hard = HardShadow().compute(Ctx(device), ins, Namespace(HardShadow.spec.coerce_params({})))["darkness"]
    assert hard.sum() > 100
    np.testing.assert_array_equal(_preview_node(device, mask, fg, bg, point, CAM), hard)
