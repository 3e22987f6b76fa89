"""Composite: shadow tint/opacity and premultiplied over, exact on constant images."""
import numpy as np
import pytest

from pixgraph.node import Namespace
from pixgraph_nodes.composite import Composite
from pixgraph_nodes.ops.composite import apply_shadow, composite, over


def test_shadow_tint_opacity_exact_on_constant_image():
    bg = np.full((4, 5, 3), [0.8, 0.5, 0.25], np.float32)
    dark = np.full((4, 5), 0.5, np.float32)
    out = apply_shadow(bg, dark, opacity=0.6, tint=(0.1, 0.2, 0.5))
    want = np.array([0.8 * (1 - 0.6 * 0.5 * 0.9), 0.5 * (1 - 0.6 * 0.5 * 0.8), 0.25 * (1 - 0.6 * 0.5 * 0.5)])
    np.testing.assert_allclose(out, np.broadcast_to(want, bg.shape), rtol=1e-6)
    # full shadow, full opacity, black tint: black; zero darkness: untouched
    np.testing.assert_array_equal(apply_shadow(bg, np.ones((4, 5), np.float32), 1.0, (0, 0, 0)), 0)
    np.testing.assert_array_equal(apply_shadow(bg, np.zeros((4, 5), np.float32), 1.0, (0, 0, 0)), bg)


def test_shadow_leaves_background_alpha_alone():
    bg = np.full((2, 2, 4), 0.5, np.float32)
    out = apply_shadow(bg, np.ones((2, 2), np.float32), 1.0, (0.0, 0.0, 0.0))
    np.testing.assert_array_equal(out[..., :3], 0)
    np.testing.assert_array_equal(out[..., 3], 0.5)


def test_alpha_over_exact():
    bg = np.full((3, 3, 3), [0.2, 0.4, 0.6], np.float32)
    a = np.full((3, 3), 0.25, np.float32)
    fg = np.full((3, 3, 4), 0.0, np.float32)
    fg[..., :3] = np.array([1.0, 0.5, 0.0]) * 0.25      # premultiplied
    fg[..., 3] = 0.25
    out = over(fg, a, bg)
    want = np.array([0.25 + 0.2 * 0.75, 0.125 + 0.4 * 0.75, 0.0 + 0.6 * 0.75])
    np.testing.assert_allclose(out, np.broadcast_to(want, out.shape), rtol=1e-6)
    # RGBA background: alpha = a + bg_a (1 - a)
    bga = np.concatenate([bg * 0.5, np.full((3, 3, 1), 0.5, np.float32)], axis=2)
    outa = over(fg, a, bga)
    np.testing.assert_allclose(outa[..., 3], 0.25 + 0.5 * 0.75, rtol=1e-6)
    with pytest.raises(ValueError, match="same size"):
        over(fg, a, np.zeros((4, 3, 3), np.float32))


def test_composite_node_shadow_then_over():
    bg = np.full((2, 3, 3), 0.5, np.float32)
    fg = np.zeros((2, 3, 4), np.float32)
    a = np.zeros((2, 3), np.float32)
    fg[0, 0] = [0.9, 0.9, 0.9, 1.0]
    a[0, 0] = 1.0
    dark = np.zeros((2, 3), np.float32)
    dark[1, :] = 1.0
    params = Namespace(Composite.spec.coerce_params({"opacity": 0.5, "tint": [0.2, 0.2, 0.2]}))
    out = Composite().compute(None, Namespace({"background": bg, "cutout": fg, "alpha": a, "shadow": dark}),
                              params)["image"]
    assert out.dtype == np.float32 and out.shape == (2, 3, 3)
    np.testing.assert_allclose(out[0, 0], 0.9)                        # cutout covers
    np.testing.assert_allclose(out[0, 1], 0.5)                        # lit background
    np.testing.assert_allclose(out[1, 2], 0.5 * (1 - 0.5 * 0.8), rtol=1e-6)  # shadowed
    no_shadow = Composite().compute(None, Namespace({"background": bg, "cutout": fg, "alpha": a,
                                                     "shadow": None}), params)["image"]
    np.testing.assert_allclose(no_shadow[1, 2], 0.5)
    np.testing.assert_allclose(composite(bg, fg, a, dark, 0.5, (0.2, 0.2, 0.2)), out)


def test_merge_cutouts_front_is_the_lower_foot():
    from pixgraph_nodes.ops.cutouts import merge_cutouts
    from pixgraph_nodes.ops.heightmaps import contact_line_height

    m1 = np.zeros((40, 40), np.float32); m1[5:30, 5:20] = 1.0     # foot row 30 (behind)
    m2 = np.zeros((40, 40), np.float32); m2[10:36, 15:25] = 1.0   # foot row 36 (in front)
    h1, h2 = contact_line_height(m1), contact_line_height(m2)
    c1 = np.zeros((40, 40, 3), np.float32); c1[m1 > 0] = [1, 0, 0]
    c2 = np.zeros((40, 40, 3), np.float32); c2[m2 > 0] = [0, 0, 1]
    mask, h, img = merge_cutouts([m1, m2], [h1, h2], [c1, c2])
    np.testing.assert_array_equal(mask, np.maximum(m1, m2))
    assert h[20, 17] == pytest.approx(36 - 20.5)     # overlap: the front cutout's height
    assert h[20, 10] == pytest.approx(30 - 20.5)
    np.testing.assert_array_equal(img[20, 17], [0, 0, 1])
    np.testing.assert_array_equal(img[20, 10], [1, 0, 0])
    assert h[0, 0] == 0 and np.all(img[0, 0] == 0)
    # order of the inputs does not matter
    mask2, hb, imgb = merge_cutouts([m2, m1], [h2, h1], [c2, c1])
    np.testing.assert_array_equal(hb, h)
    np.testing.assert_array_equal(imgb, img)


@pytest.mark.parametrize("channels", [3, 4])
def test_box_limited_composite_equals_the_formula_everywhere(channels):
    """The composite works only over the boxes the shadow and the cutout reach; the
    result is the plain per-pixel formula on every pixel (also where a premultiplied
    colour has no alpha: additive light), and the inputs are not modified."""
    rng = np.random.default_rng(3)
    H, W = 90, 120
    bg = rng.random((H, W, channels), dtype=np.float32)
    dark = np.zeros((H, W), np.float32)
    dark[20:50, 30:70] = rng.random((30, 40), dtype=np.float32) * 1.3 - 0.1     # out of [0, 1] too
    a = np.zeros((H, W), np.float32)
    a[40:80, 60:100] = rng.random((40, 40), dtype=np.float32)
    fg = np.zeros((H, W, 4), np.float32)
    fg[..., :3] = a[..., None] * rng.random((H, W, 3), dtype=np.float32)
    fg[..., 3] = a
    fg[5, 5, :3] = 0.3                                        # colour without coverage
    keep = [x.copy() for x in (bg, dark, fg, a)]
    tint = np.array([0.1, 0.2, 0.3], np.float32)
    d = np.clip(dark, 0, 1)[..., None]
    shadowed = bg.copy()
    shadowed[..., :3] = bg[..., :3] * (1 - 0.7 * d * (1 - tint))
    want = shadowed.copy()
    want[..., :3] = fg[..., :3] + shadowed[..., :3] * (1 - a[..., None])
    if channels == 4:
        want[..., 3] = a + shadowed[..., 3] * (1 - a)
    got = composite(bg, fg, a, dark, 0.7, tint)
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(apply_shadow(bg, dark, 0.7, tint), shadowed, rtol=1e-6, atol=1e-7)
    for x, k in zip((bg, dark, fg, a), keep):
        np.testing.assert_array_equal(x, k)
