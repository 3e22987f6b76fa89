"""PlaceCutout: a cutout of any size on the background's canvas; the camera takes the
background's size; inputs a user has (no alpha, a mask file, a height map of another size)."""
import numpy as np
import pytest

from pixgraph.engine import NodeInputError
from pixgraph.session import Session
from pixgraph_nodes.ops.heightmaps import contact_line_height
from pixgraph_nodes.ops.imageio import read_mask, write_image
from pixgraph_nodes.ops.lights import foot_of_mask
from pixgraph_nodes.ops.placement import place_cutout, resize_map


def _box_cutout(h=60, w=30, colour=(0.9, 0.1, 0.05)):
    """A premultiplied RGBA box with a 2 px transparent margin and its contact-line heights."""
    a = np.zeros((h, w), np.float32)
    a[2:-2, 2:-2] = 1.0
    rgba = np.concatenate([a[:, :, None] * np.array(colour, np.float32), a[:, :, None]], axis=2)
    return rgba, a, contact_line_height(a)


@pytest.mark.parametrize("s", [0.5, 1.0, 2.0, 3.0])
def test_foot_lands_on_the_point_and_heights_scale_by_s(s):
    rgba, a, h = _box_cutout()
    img, alpha, ph = place_cutout(rgba, a, h, (300, 400), (200.0, 250.0), s)
    assert img.shape == (300, 400, 4) and alpha.shape == ph.shape == (300, 400)
    u, v = foot_of_mask(alpha)
    assert abs(u - 200.0) <= 1.0 and abs(v - 250.0) <= 1.0
    # the box is 56 px tall in the cutout: s * 56 on the canvas, and so is its top's pixel height
    rows = np.nonzero((alpha > 0.5).any(axis=1))[0]
    assert abs((rows[-1] - rows[0] + 1) - 56 * s) <= 1.0
    assert ph.max() == pytest.approx(h.max() * s, abs=0.6 * max(1.0, s))
    # every placed height is the contact-line height of the placed box (a box's heights are linear)
    inner = alpha > 0.999
    np.testing.assert_allclose(ph[inner], contact_line_height(alpha)[inner], atol=0.6 * max(1.0, s))


def test_steep_faces_are_blended_and_steps_are_not():
    """A face seen at a grazing angle changes pixel height by many px per px but is
    one plane: placed at s = 1.5 its heights are the linear interpolation, s times
    (no staircase from nearest-pixel sampling). A step between two surfaces is
    not blended: no placed height lies strictly between the two levels."""
    h, w = 40, 40
    a = np.zeros((h, w), np.float32)
    a[2:-2, 2:-2] = 1.0
    x = np.arange(w, dtype=np.float32)[None, :].repeat(h, 0)
    ramp = (100.0 + 6.0 * (x + 0.5)) * a                       # 6 px of height per px
    rgba = np.concatenate([a[:, :, None].repeat(3, 2), a[:, :, None]], axis=2)
    s = 1.5
    _, pa, ph = place_cutout(rgba, a, ramp, (120, 120), (60.0, 100.0), s)
    ax, ay = foot_of_mask(a)
    X = ax + ((np.arange(120) + 0.5) - 60.0) / s               # source x of each canvas column
    inner = (pa > 0.999) & (np.abs(np.arange(120)[None, :] - 60) < 20 * s - 4)
    expect = s * (100.0 + 6.0 * X)[None, :].repeat(120, 0)
    assert inner.sum() > 500
    np.testing.assert_allclose(ph[inner], expect[inner], atol=1e-2)
    step = np.where(x < 20, 100.0, 160.0).astype(np.float32) * a
    _, pa, ph = place_cutout(rgba, a, step, (120, 120), (60.0, 100.0), s)
    inside = pa > 0.999
    assert not ((ph[inside] > 100.0 * s + 1e-3) & (ph[inside] < 160.0 * s - 1e-3)).any()


def test_premultiplied_edges_keep_their_colour():
    rgba, a, h = _box_cutout()
    img, alpha, _ = place_cutout(rgba, a, None, (200, 200), (100.3, 150.7), 1.37)
    edge = (alpha > 0.05) & (alpha < 0.95)
    assert edge.sum() > 50
    straight = img[edge, :3] / alpha[edge, None]
    np.testing.assert_allclose(straight, np.broadcast_to([0.9, 0.1, 0.05], straight.shape), atol=1e-4)
    np.testing.assert_allclose(img[..., 3], alpha)


def test_flip_mirrors_about_the_foot_and_border_crops():
    rgba, a, h = _box_cutout()
    a2 = a.copy()
    a2[2:20, 2:10] = 0.0                               # notch top-left: not symmetric
    rgba2 = rgba * a2[:, :, None] / np.maximum(a, 1e-6)[:, :, None]
    _, al, _ = place_cutout(rgba2, a2, None, (100, 101), (50.5, 80.0), 1.0)
    _, fl, _ = place_cutout(rgba2, a2, None, (100, 101), (50.5, 80.0), 1.0, flip=True)
    np.testing.assert_allclose(fl, al[:, ::-1], atol=1e-6)
    # half off the left border: cropped, nothing wraps around
    _, crop, _ = place_cutout(rgba, a, h, (100, 100), (3.0, 80.0), 1.0)
    assert crop[:, :5].sum() > 0 and crop[:, 50:].sum() == 0 and 0.4 < crop.sum() / a.sum() < 0.7


def test_height_map_of_another_size_is_resized_with_heights_scaled():
    _, a, h = _box_cutout(120, 60)
    small = resize_map(h, (60, 30))
    assert small.shape == (60, 30)
    assert small.max() == pytest.approx(h.max() / 2, abs=0.6)
    with pytest.raises(ValueError, match="aspect"):
        resize_map(h, (60, 60))


@pytest.fixture(scope="module")
def session():
    return Session(disk_cache=None)


def _graph(session, tmp_path, cutout, mask=None, height=None, **place):
    photo = np.full((240, 320, 3), 0.4, np.float32)
    b = session.builder(base_dir=str(tmp_path))
    b.add("pixgraph.InputImage", "cutout")
    b.add("pixgraph.InputImage", "photo")
    b.add("pixgraph.Camera", "cam", hfov=50, horizon=60)
    b.add("pixgraph.PlaceCutout", "place", **({"foot": [160, 200]} | place))
    b.connect("photo.image", "cam.image")
    b.connect("cutout.image", "place.cutout")
    b.connect("photo.image", "place.background")
    bind = {"cutout": cutout, "photo": photo}
    if mask is not None:
        b.add("pixgraph.InputMask", "m")
        b.connect("m.mask", "place.mask")
        bind["m"] = mask
    if height is not None:
        b.add("pixgraph.InputPixelHeight", "h")
        b.connect("h.height", "place.height")
        bind["h"] = height
    for o in ("image", "alpha", "height"):
        b.output(o, f"place.{o}")
    b.output("camera", "cam.camera")
    return b.build(), bind


def test_node_places_on_the_canvas_and_camera_takes_its_size(session, tmp_path):
    rgba, a, h = _box_cutout()
    g, bind = _graph(session, tmp_path, rgba, height=resize_map(h, (120, 60)), scale=2.0)
    out = session.run(g, bind=bind)
    assert out["alpha"].shape == (240, 320) and out["camera"].width == 320 and out["camera"].height == 240
    assert out["height"].max() == pytest.approx(h.max() * 2, abs=1.2)


def test_rgb_cutout_needs_a_mask(session, tmp_path):
    rgb = np.full((40, 20, 3), 0.5, np.float32)
    g, bind = _graph(session, tmp_path, rgb)
    with pytest.raises(NodeInputError, match="no alpha channel"):
        session.run(g, bind=bind)
    m = np.zeros((40, 20), np.float32)
    m[5:35, 5:15] = 1.0
    g, bind = _graph(session, tmp_path, rgb, mask=m)
    out = session.run(g, bind=bind)
    assert out["alpha"].sum() == pytest.approx(m.sum(), rel=0.02)       # the mask, not the full frame
    np.testing.assert_allclose(out["image"][..., :3][out["alpha"] > 0.99], 0.5, atol=1e-5)


def test_mask_files_png_and_npy(tmp_path):
    m = np.zeros((8, 6), np.float32)
    m[2:6, 1:5] = 1.0
    m[0, 0] = 128 / 255
    write_image(tmp_path / "m.png", m)                 # grey PNG: linear_to_srgb would change 0.502
    np.save(tmp_path / "m255.npy", (m * 255).astype(np.float64))
    np.save(tmp_path / "mbool.npy", m > 0.9)
    np.testing.assert_allclose(read_mask(tmp_path / "m255.npy"), m, atol=1e-6)
    np.testing.assert_array_equal(read_mask(tmp_path / "mbool.npy"), (m > 0.9).astype(np.float32))
    got = read_mask(tmp_path / "m.png")
    assert got[3, 2] == 1.0 and got[7, 5] == 0.0


@pytest.mark.datagen
@pytest.mark.parametrize("s", [1.5, 0.5])
def test_placed_equals_rendered_at_that_size(device, s):
    """A cutout rendered at 256^2 and placed at scale s, foot p, against the same scene
    rendered directly at 256 s (Mitsuba ray casts, lab/placement.py): the soft shadows
    agree (IoU of darkness > 0.5 over the background) and the heights scaled by s."""
    pytest.importorskip("mitsuba")
    pytest.importorskip("trimesh")
    from pixgraph_lab.placement import measure

    r = measure(device, 2, 256, s, solid=True)
    assert r["mask_iou"] >= 0.99
    assert r["soft_iou"] >= 0.98, r
    assert r["height_median_abs_px"] <= 0.05
    assert r["height_ratio"] == pytest.approx(s, rel=0.01)


def _disk_coverage(n, cx, cy, r, ss=8):
    """Exact-ish coverage of a disk on an n x n grid (ss x ss supersamples per pixel)."""
    o = (np.arange(ss) + 0.5) / ss
    y = np.arange(n)[:, None, None, None] + o[None, None, :, None]
    x = np.arange(n)[None, :, None, None] + o[None, None, None, :]
    return (((x - cx) ** 2 + (y - cy) ** 2) <= r * r).mean(axis=(2, 3))


def _contour_offsets(al, cx, cy, r):
    """Distance [px] of the 0.5 crossing of ``al`` from the circle, along 360 rays."""
    out = []
    rs = np.linspace(r - 8, r + 8, 321)
    for t in np.linspace(0, 2 * np.pi, 360, endpoint=False):
        x, y = cx + rs * np.cos(t) - 0.5, cy + rs * np.sin(t) - 0.5
        x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
        fx, fy = x - x0, y - y0
        v = (al[y0, x0] * (1 - fx) * (1 - fy) + al[y0, x0 + 1] * fx * (1 - fy)
             + al[y0 + 1, x0] * (1 - fx) * fy + al[y0 + 1, x0 + 1] * fx * fy)
        i = np.nonzero((v[:-1] >= 0.5) & (v[1:] < 0.5))[0][0]
        out.append(rs[i] + (v[i] - 0.5) / (v[i] - v[i + 1]) * (rs[1] - rs[0]) - r)
    return np.array(out)


@pytest.mark.parametrize("radius, cx", [(20.0, 32.0), (13.3, 32.4)])
def test_a_hard_mask_enlarged_gets_a_smooth_antialiased_edge(radius, cx):
    """A binary disk (pixel centres inside the circle) enlarged 4x: bilinear resampling
    keeps its staircase (a 4 px ramp along pixel steps); ``smooth_edge`` draws the
    smooth contour one pixel wide. Against the exact coverage of the true disk."""
    yy, xx = np.mgrid[0:64, 0:64] + 0.5
    a = (((xx - cx) ** 2 + (yy - 32) ** 2) <= radius ** 2).astype(np.float32)
    rgba = np.concatenate([a[:, :, None] * np.array([0.5, 0.3, 0.2], np.float32), a[:, :, None]], axis=2)
    s, R = 4.0, 4.0 * radius
    cy = 250.0 - R
    exact = _disk_coverage(300, 150.0, cy, R)
    dist = np.hypot(np.arange(300)[None, :] + 0.5 - 150.0, np.arange(300)[:, None] + 0.5 - cy)
    band = np.abs(dist - R) < 3
    res = {}
    for smooth in (False, True):
        img, al, _ = place_cutout(rgba, a, None, (300, 300), (150.0, 250.0), s, anchor=(cx, 32 + radius),
                                  smooth_edge=smooth)
        off = _contour_offsets(al, 150.0, cy, R)
        res[smooth] = dict(area=al.sum() / exact.sum() - 1, band=np.sqrt(np.mean((al - exact)[band] ** 2)),
                           contour=np.sqrt(np.mean(off ** 2)), soft=((al > 0.1) & (al < 0.9)).sum())
        if smooth:   # the new edge pixels carry the cutout's own colour
            edge = al > 0.02
            np.testing.assert_allclose(img[edge, :3] / al[edge, None],
                                       np.broadcast_to([0.5, 0.3, 0.2], (edge.sum(), 3)), atol=1e-4)
            np.testing.assert_allclose(img[..., 3], al)
    b, sm = res[False], res[True]
    # measured: band RMSE 0.26 -> 0.16 / 0.18, outline RMS 0.86 -> 0.44 / 0.51 px, area within 0.3 %
    assert sm["band"] < 0.75 * b["band"] and sm["band"] < 0.2
    assert sm["contour"] < 0.65 * b["contour"] and sm["contour"] < 0.6
    assert abs(sm["area"]) < 0.005
    assert sm["soft"] < 0.5 * b["soft"]          # one pixel wide, not a 4 px ramp


def test_soft_mattes_are_not_refined():
    from pixgraph_nodes.ops.placement import is_hard_mask
    yy, xx = np.mgrid[0:64, 0:64] + 0.5
    d = np.hypot(xx - 32, yy - 32)
    assert is_hard_mask((d <= 20).astype(np.float32))
    soft = np.clip(20.5 - d, 0.0, 1.0).astype(np.float32)      # antialiased: one ramp pixel per outline pixel
    assert not is_hard_mask(soft)
    rgba = np.concatenate([soft[:, :, None].repeat(3, 2), soft[:, :, None]], axis=2)
    a1 = place_cutout(rgba, soft, None, (200, 200), (100.0, 190.0), 3.0, smooth_edge=True)[1]
    a0 = place_cutout(rgba, soft, None, (200, 200), (100.0, 190.0), 3.0)[1]
    assert np.array_equal(a0, a1)


@pytest.mark.parametrize("h, w, H, W, s, dy, dx", [(300, 200, 900, 600, 3.0, -3.3, 2.1),
                                                   (500, 400, 200, 160, 0.37, 0.0, 0.0),
                                                   (64, 80, 64, 80, 1.0, 0.25, -0.5),
                                                   (100, 120, 257, 300, 2.3, 40.0, -60.0)])
def test_resampling_by_taps_is_the_dense_weights_product(h, w, H, W, s, dy, dx):
    """``_resample`` (taps, banded) equals ``wy @ plane @ wx.T`` with the dense weights,
    enlarging, shrinking, at scale 1 and with the cutout partly off the canvas."""
    from pixgraph_nodes.ops import placement as P
    planes = np.random.default_rng(5).uniform(0, 1, (h, w, 3)).astype(np.float32)
    sup = max(1.0, 1.0 / s)
    wy = P._weights(h, (np.arange(H) + 0.5) / s + dy, sup)
    wx = P._weights(w, (np.arange(W) + 0.5) / s + dx, sup)
    want = np.stack([wy @ planes[:, :, c].astype(np.float64) @ wx.T for c in range(3)], axis=2)
    got = P._resample(planes, wy, wx, band=37)
    np.testing.assert_allclose(got, want.astype(np.float32), rtol=0, atol=2e-7)
    assert (got[want == 0] == 0).all()


def test_resampling_holds_no_float64_copy_of_the_source(monkeypatch):
    """``_resample`` reads the float32 source as it is: a float64 copy of every plane
    at once (6 planes: colour, alpha, height) was twice the source's bytes, held for
    the whole resampling (a 20 MP cutout: ~1 GB). Allocations traced by numpy."""
    import tracemalloc

    from pixgraph_nodes.ops import placement as P
    monkeypatch.setenv("PIXGRAPH_THREADS", "1")
    h, w = 600, 400
    planes = np.random.default_rng(2).uniform(0, 1, (h, w, 6)).astype(np.float32)
    wy = P._weights(h, np.arange(h) + 0.5, 1.0)
    wx = P._weights(w, np.arange(w) + 0.5, 1.0)
    tracemalloc.start()
    try:
        out = P._resample(planes, wy, wx)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    np.testing.assert_allclose(out, planes, atol=1e-6)          # scale 1, no shift: the source
    assert peak - out.nbytes < planes.nbytes, (peak, out.nbytes, planes.nbytes)
