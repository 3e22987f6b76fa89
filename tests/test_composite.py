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
