"""SSN++ on any image size (ops/ssn_crop.py, ops/resample.py, ops/upsample.py): the
window keeps the trained scale without squashing, a large non-square image gives
the 256^2 result, the paste leaves no halo and nothing outside the shadow's
reach, and a softness outside the trained range is clamped with a warning."""
import pathlib

import numpy as np
import pytest
from scipy import ndimage

from _shadow_scenes import figure, pole, wall_bg
from pixgraph.session import Session
from pixgraph_nodes.ops import ssn, ssn_crop
from pixgraph_nodes.ops.buffers import buffer_channels
from pixgraph_nodes.ops.camera import Camera
from pixgraph_nodes.ops.lights import disk_extremes, disk_light, disk_samples, light_point
from pixgraph_nodes.ops.resample import Window, resize
from pixgraph_nodes.ops.shadow import hard_shadow, soft_shadow
from pixgraph_nodes.ops.upsample import masked_resize
from pixgraph_nodes.ssn_soft_shadow import load_shipped

GRAPH = pathlib.Path(__file__).resolve().parents[1] / "graphs" / "ssn_wall_corner.yaml"

CAM = Camera(256, 256, 50.0, horizon=60.0)
#: the 256^2 figure scene enlarged 4x (figure() is analytic at any size) and cut
#: to rows 300..1000: 1024 x 700, whose horizon moves with the cut
BIG_ROWS = (300, 1000)
CAM_BIG = Camera(1024, 700, 50.0, horizon=60.0 * 4 - BIG_ROWS[0])


def _light(offset, radius):
    foot = CAM.back_project(np.array([128.0]), np.array([0.88 * 256]), np.array([0.0]))[0][0]
    return disk_light(tuple(np.asarray(offset) + foot * [1, 0, 1]), radius, target=tuple(foot))


def _render(device, scene, cam, light):
    m, fg, bg = scene
    return ssn_crop.render(device, load_shipped("ssnpp"), m, fg, bg, light_point(light, cam),
                           disk_extremes(light, cam), ssn.softness_of(light, cam, m, fg))


def test_window_keeps_one_scale_and_the_trained_object_size():
    # a 600 px tall cutout in a 1300 x 893 photo, its shadow reaching right
    win = ssn_crop.choose_window(893, 1300, (400, 150, 1250, 800), 600.0)
    assert win.kx == pytest.approx(win.ky, rel=0.01)            # no squashing
    assert 600 * win.ky == pytest.approx(ssn_crop.OBJECT_PX[1], rel=0.01)
    assert win.out_w % 16 == 0 and win.out_h % 16 == 0 and min(win.out_w, win.out_h) >= 256
    # the window holds the extent (+ margin where the image allows)
    assert win.x0 <= 400 and win.x0 + win.w >= 1250 and win.y0 <= 150 and win.y0 + win.h >= 800
    # an image already at the trained scale is its own window
    assert ssn_crop.choose_window(256, 256, (0, 0, 256, 256), 100.0) == Window(0, 0, 256, 256, 256, 256)


def test_window_maps_pixel_height_space_exactly(device):
    # a crop at scale 1: the hard shadow traced in the window is the crop of the image's
    H, W = 200, 300
    mask, fg = pole(H, W, 140, 6, 60, 150)
    bg = wall_bg(H, W, 90)
    L = np.array([60.0, 20.0, 180.0, 1.0], np.float32)
    full = hard_shadow(device, mask, fg, bg, L, 1.0)
    win = Window(40, 10, 240, 180, 240, 180)
    m, f, b = win.scene(mask, fg, bg)
    inner = hard_shadow(device, m, f, b, win.light_points(L), 1.0)
    assert np.array_equal(inner, full[10:190, 40:280])
    assert (inner < 0.5).sum() > 300                            # a real shadow was compared


def test_masked_resize_does_not_bleed_across_the_outline():
    # darkness 1 inside the cutout (meaningless there), 0 outside: a plain
    # enlargement greys the background along the outline, the masked one cannot
    lo_mask = np.zeros((32, 32), np.float32)
    lo_mask[8:24, 10:20] = 1
    hi_mask = resize(lo_mask, (128, 128)) > 0.5
    plain = resize(lo_mask, (128, 128))
    masked = masked_resize(lo_mask, lo_mask, hi_mask, (128, 128))
    assert plain[~hi_mask].max() > 0.3
    assert masked[~hi_mask].max() == 0.0 and masked[hi_mask].min() == 1.0


@pytest.mark.parametrize("lo_shape, hi_shape", [((40, 30), (160, 130)), ((37, 53), (37, 200)), ((64, 64), (64, 64))])
def test_masked_resize_in_bands_equals_one_pass_and_the_reference(lo_shape, hi_shape):
    """Made a band of rows at a time: any band size gives the same pixels, which
    are the normalised convolution written out with whole-image resizes."""
    rng = np.random.default_rng(1)
    H, W = hi_shape
    yy, xx = np.mgrid[0:H, 0:W]
    hi = (((yy - H / 2) / (H / 3)) ** 2 + ((xx - W / 2) / (W / 4)) ** 2 < 1).astype(np.float32)
    mlo = resize(hi, lo_shape)
    lo = rng.random(lo_shape).astype(np.float32)
    ref = resize(lo, hi_shape)
    for side_lo, side_hi in ((mlo <= 0.5, hi <= 0.5), (mlo > 0.5, hi > 0.5)):
        wgt = side_lo.astype(np.float32)
        den, num = resize(wgt, hi_shape), resize(lo * wgt, hi_shape)
        ok = side_hi & (den > 1e-3)
        ref[ok] = num[ok] / den[ok]
    one = masked_resize(lo, mlo, hi, hi_shape, band=100000)
    for band in (1, 7, 64):
        assert np.array_equal(masked_resize(lo, mlo, hi, hi_shape, band=band), one)
    np.testing.assert_allclose(one, ref, atol=1e-6)


@pytest.mark.parametrize("offset, radius", [((1.0, 1.5, -1.0), 0.05), ((-1.5, 2.5, -2.0), 0.3),
                                            ((0.5, 3.0, 2.0), 0.5)])
def test_large_non_square_image_matches_the_256_run(device, offset, radius):
    small = figure(256, 256)
    big = tuple(a[BIG_ROWS[0]:BIG_ROWS[1]] for a in figure(1024, 1024))
    L = _light(offset, radius)
    d, info = _render(device, small, CAM, L)
    D, info_big = _render(device, big, CAM_BIG, L)
    # both run the network on a window with the cutout ~120 px tall
    assert info.object_px * info.window.ky == pytest.approx(info_big.object_px * info_big.window.ky, rel=0.03)
    rows = slice(BIG_ROWS[0] // 4, BIG_ROWS[1] // 4)
    out = small[0][rows] < 0.5
    shrunk = resize(D, (175, 256))
    err = float(np.sqrt(np.mean((shrunk - d[rows])[out] ** 2)))
    # the whole-frame squeeze this replaces (buffer channels at full size, resized to 256^2)
    b = buffer_channels(device, big[0], big[1], big[2], light_point(L, CAM_BIG), disk_extremes(L, CAM_BIG))
    old = resize(ssn.predict(load_shipped("ssnpp"), b, info_big.softness), (175, 256))
    err_old = float(np.sqrt(np.mean((old - d[rows])[out] ** 2)))
    # measured: 0.014-0.026 (squeeze: 0.010-0.115)
    assert err < 0.035 and err < err_old


def test_no_halo_and_nothing_outside_the_shadows_reach(device):
    big = tuple(a[BIG_ROWS[0]:BIG_ROWS[1]] for a in figure(1024, 1024))
    L = _light((1.0, 1.5, -1.0), 0.05)       # light behind: the shadow falls forward, the wall stays lit
    D, info = _render(device, big, CAM_BIG, L)
    inside = big[0] > 0.5
    lit = soft_shadow(device, big[0], big[1], big[2], disk_samples(L, CAM_BIG, 16), 1.0 / info.window.ky)
    ring = (ndimage.distance_transform_edt(~inside) <= 3) & ~inside & (lit >= 1.0)
    # measured 0.026; 0.18 when the cutout's self-shadow counted in the gate's union, 0.21 with the squeeze
    assert ring.sum() > 1000 and D[ring].mean() < 0.05
    # 30 network px (134 image px) from the classical shadow and the cutout: exactly 0
    far = ndimage.distance_transform_edt(~((lit < 1.0) | inside)) > 30 / info.window.ky
    assert far.sum() > 100_000 and D[far].max() == 0.0


def test_softness_outside_the_trained_range_is_clamped_with_a_warning(device):
    m, fg, bg = figure(256, 256)
    L = _light((-1.5, 2.5, -2.0), 0.3)
    run = lambda soft: ssn_crop.render(device, load_shipped("ssnpp"), m, fg, bg, light_point(L, CAM),
                                       disk_extremes(L, CAM), soft)
    (d75, i75), (d45, i45), (d30, _) = run(0.75), run(0.45), run(0.30)
    assert i75.clamped and i75.softness == 0.45 and not i45.clamped
    assert np.array_equal(d75, d45) and not np.array_equal(d45, d30)
    s = Session(disk_cache=None)
    g = s.graph(GRAPH)
    events = []
    # radius 3 at distance 4 from the light's target: softness ~0.75 (trained <= 0.45)
    s.run(g, outputs=["shadow.darkness"], params={"light.radius": 3.0}, on_event=events.append)
    logs = [e.message for e in events if type(e).__name__ == "NodeLog" and e.node_id == "shadow"]
    assert any(m.startswith("warning: light softness") and "0.45" in m for m in logs), logs
    assert s.last_run.logs["shadow"] == logs
    quiet = []
    s.run(g, outputs=["shadow.darkness"], params={"light.radius": 0.5}, on_event=quiet.append)
    assert not any("warning" in e.message for e in quiet if type(e).__name__ == "NodeLog")
