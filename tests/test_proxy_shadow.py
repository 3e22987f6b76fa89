"""The classical soft shadow at a proxy resolution (ops/upsample.py, SoftShadow's
``proxy`` param) against the full-resolution trace."""
import pathlib

import numpy as np
import pytest

from _shadow_scenes import figure
from pixgraph.session import Session
from pixgraph_nodes.ops.camera import Camera
from pixgraph_nodes.ops.lights import disk_light, disk_samples
from pixgraph_nodes.ops.shadow import soft_shadow
from pixgraph_nodes.ops.upsample import proxy_soft_shadow

GRAPHS = pathlib.Path(__file__).resolve().parents[1] / "graphs"


def _scene(n=768):
    m, fg, bg = figure(n, n)
    cam = Camera(n, n, 50.0, horizon=0.25 * n)
    foot = cam.back_project(np.array([n / 2]), np.array([0.88 * n]), np.array([0.0]))[0][0]
    return m, fg, bg, cam, foot


def test_no_proxy_at_or_below_its_size_is_the_plain_trace(device):
    m, fg, bg, cam, foot = _scene(256)
    S = disk_samples(disk_light(tuple(foot + [-1.5, 2.5, -2.0]), 0.3, target=tuple(foot)), cam, 8)
    full = soft_shadow(device, m, fg, bg, S, 1.0)
    assert np.array_equal(proxy_soft_shadow(device, m, fg, bg, S, 1.0, 256), full)
    assert np.array_equal(proxy_soft_shadow(device, m, fg, bg, S, 1.0, 4096), full)
    with pytest.raises(ValueError, match="at least 16"):
        proxy_soft_shadow(device, m, fg, bg, S, 1.0, 8)


@pytest.mark.parametrize("offset, radius", [((-1.5, 2.5, -2.0), 0.3), ((1.0, 1.5, 1.0), 0.05)])
def test_a_proxy_three_times_smaller_stays_close_to_the_full_trace(device, offset, radius):
    m, fg, bg, cam, foot = _scene(768)
    S = disk_samples(disk_light(tuple(np.asarray(offset) + foot * [1, 0, 1]), radius, target=tuple(foot)), cam, 16)
    full = soft_shadow(device, m, fg, bg, S, 1.0)
    out = m < 0.5
    assert (full[out] < 0.5).sum() > 5_000                   # a large shadow is compared
    err = {p: float(np.sqrt(np.mean((proxy_soft_shadow(device, m, fg, bg, S, 1.0, p) - full)[out] ** 2)))
           for p in (256, 384)}
    # measured 0.016-0.018 at 256 px, 0.009-0.011 at 384 px
    assert err[256] < 0.025 and err[384] < 0.016 and err[384] < err[256]


def test_soft_shadow_node_proxy_param(device):
    s = Session(device=device, disk_cache=None)
    g = s.graph(GRAPHS / "ground_shadow.yaml")
    run = lambda p: s.run(g, outputs=["shadow.darkness"], params={"shadow.proxy": p})["shadow.darkness"]
    full = run(0)
    assert np.array_equal(run(1024), full)                  # the default leaves 512^2 images alone
    out = s.run(g, outputs=["cutout.alpha"])["cutout.alpha"] < 0.5
    # measured 0.009
    assert np.sqrt(np.mean((run(256) - full)[out] ** 2)) < 0.015


@pytest.mark.parametrize("shape,side", [((300, 410), 128), ((384, 512), 256), ((333, 500), 97)])
def test_proxy_scene_is_the_window_scene(shape, side):
    """The proxy's scene, its coverage and height resized only over the cutout's box,
    is bit for bit Window.scene, its background height up to float rounding
    (integer and odd shrink factors, a cutout off centre, a non-finite background
    height)."""
    from pixgraph_nodes.ops.resample import Window
    from pixgraph_nodes.ops.upsample import proxy_scene
    H, W = shape
    m, fg, bg = figure(H, W)
    m = np.roll(m, (H // 7, -W // 5), axis=(0, 1))
    fg = np.roll(fg, (H // 7, -W // 5), axis=(0, 1))
    bg = bg.copy()
    bg[3, 5] = np.nan
    win = Window.whole(H, W, side)
    ref, got = win.scene(m, fg, bg), proxy_scene(win, m, fg, bg)
    assert all(a.shape == b.shape for a, b in zip(ref, got))
    assert np.array_equal(ref[0], got[0]) and np.array_equal(ref[1], got[1])
    np.testing.assert_allclose(got[2], ref[2], rtol=1e-5, atol=1e-4)
    empty = proxy_scene(win, np.zeros_like(m), fg, bg)
    assert not empty[0].any() and not empty[1].any() and np.array_equal(empty[2], got[2])


@pytest.mark.parametrize("box", [(0, 200, 0, 260), (37, 121, 50, 199), (150, 200, 0, 13)])
def test_masked_resize_of_a_box_is_that_part_of_the_whole(box):
    """Made on a box of output pixels (reading only the proxy rows that box needs),
    the enlargement is bit for bit that part of the whole-image enlargement."""
    from pixgraph_nodes.ops.resample import resize
    from pixgraph_nodes.ops.upsample import masked_resize
    rng = np.random.default_rng(3)
    H, W = 200, 260
    yy, xx = np.mgrid[0:H, 0:W]
    hi = (((yy - 90) / 50.0) ** 2 + ((xx - 120) / 40.0) ** 2 < 1).astype(np.float32)
    mlo = resize(hi, (41, 53))
    lo = rng.random((41, 53)).astype(np.float32)
    whole = masked_resize(lo, mlo, hi, (H, W))
    r0, r1, c0, c1 = box
    assert np.array_equal(masked_resize(lo, mlo, hi, (H, W), band=17, box=box), whole[r0:r1, c0:c1])
