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
