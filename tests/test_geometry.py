"""Reconstruct3D, background templates, cutout heuristics and pixel-height files."""
import math

import numpy as np
import pytest

from pixgraph.node import Namespace
from pixgraph_nodes.background_height import BackgroundHeight
from pixgraph_nodes.cutout_height import CutoutHeight
from pixgraph_nodes.ops import heightmaps as hm
from pixgraph_nodes.ops.camera import Camera
from pixgraph_nodes.ops.geometry import reconstruct_geometry
from pixgraph_nodes.reconstruct3d import Reconstruct3D

CAM = Camera(320, 240, hfov=60.0, horizon=60.0, cam_height=1.5)


class Ctx:
    device = None
    graph_dir = None
    scale = 1.0

    def progress(self, *a):
        pass

    def check_cancelled(self):
        pass


def params_of(cls, **over):
    return Namespace(cls.spec.coerce_params(over))


def test_reconstruct_then_project_gives_back_uvh():
    h = hm.back_wall(CAM.width, CAM.height, row=170.0, slope=0.1)
    out = Reconstruct3D().compute(Ctx(), Namespace({"camera": CAM, "height": h}), Namespace({}))
    valid = out["valid"] > 0
    assert valid.sum() > 0.5 * valid.size
    uvh, D = CAM.project(out["positions"].astype(np.float64))
    u, v = CAM.pixel_grid()
    assert np.all(D[valid] > 0)
    err = np.abs(uvh - np.stack([u, v, h], -1))[valid]
    assert err.max() < 1e-4 * max(1.0, 1.0), err.max(axis=0)


def test_invalid_at_or_above_horizon_and_never_behind_camera():
    h = np.zeros((CAM.height, CAM.width), np.float32)
    g = reconstruct_geometry(CAM, h)
    rows_valid = g.valid[:, 0] > 0
    # pixel centres v = i + 0.5; valid iff v > horizon = 60
    assert not rows_valid[:60].any() and rows_valid[60:].all()
    assert np.all(g.position[~(g.valid > 0)] == 0)
    assert np.all(g.depth[g.valid > 0] > 0)
    # a pixel whose foot is exactly on the horizon is invalid
    h2 = np.zeros_like(h)
    h2[40, 10] = 60.0 - 40.5
    assert reconstruct_geometry(CAM, h2).valid[40, 10] == 0


def test_normals_ground_up_and_back_wall_facing_camera():
    h = hm.back_wall(CAM.width, CAM.height, row=150.0)
    g = reconstruct_geometry(CAM, h)
    ground_px = g.normal[200, 100]
    wall_px = g.normal[120, 100]
    np.testing.assert_allclose(ground_px, [0, 1, 0], atol=1e-5)
    np.testing.assert_allclose(wall_px, [0, 0, 1], atol=1e-5)
    # wall points all lie on one vertical plane Z = const, ground points on Y = 0
    wall = (h > 1.0) & (g.valid > 0)
    assert np.ptp(g.position[..., 2][wall]) < 1e-4 * abs(g.position[..., 2][wall].mean())
    ground = (h == 0) & (g.valid > 0)
    assert np.abs(g.position[..., 1][ground]).max() < 1e-6


def test_back_wall_two_points_and_row_slope_agree():
    a = hm.back_wall(200, 100, row=70.0, slope=0.2)
    b = hm.wall_from_junction(200, 100, [(0.0, 70.0 - 0.2 * 100), (200.0, 70.0 + 0.2 * 100)])
    np.testing.assert_allclose(a, b, atol=1e-4)
    # h = v_wall(u) - v above the junction: column 150 (u = 150.5): v_wall = 70 + 0.2 * 50.5
    assert a[30, 150] == pytest.approx(70 + 0.2 * 50.5 - 30.5, abs=1e-4)
    assert a[99, 150] == 0.0


def test_wall_corner_is_two_straight_junctions():
    h = hm.wall_corner(300, 200, corner=(150.0, 120.0), left_slope=-0.25, right_slope=0.5)
    # just above the junction h is the distance to the junction row of that column
    for col, vw in ((20, 120 + (20.5 - 150) * -0.25), (280, 120 + (280.5 - 150) * 0.5)):
        assert h[10, col] == pytest.approx(vw - 10.5, abs=1e-4)
    # each wall's 3D points lie on one vertical plane: X, Z affine => constant normal
    cam = Camera(300, 200, hfov=70, horizon=40, cam_height=1.0)
    g = reconstruct_geometry(cam, h)
    nl, nr = g.normal[60, 40], g.normal[60, 260]
    assert abs(nl[1]) < 1e-5 and abs(nr[1]) < 1e-5  # vertical walls
    assert nl[0] > 0.1 and nr[0] < -0.1              # concave corner: walls face each other
    assert nl[2] > 0 and nr[2] > 0


def test_two_corners_back_wall_between():
    h = hm.two_corners(400, 200, (100.0, 130.0), (300.0, 130.0), -0.3, 0.3)
    assert h[30, 200] == pytest.approx(130 - 30.5, abs=1e-4)
    assert h[30, 10] == pytest.approx(130 + (10.5 - 100) * -0.3 - 30.5, abs=1e-4)
    assert h[30, 390] == pytest.approx(130 + (390.5 - 300) * 0.3 - 30.5, abs=1e-4)


def test_steps_treads_flat_and_risers_vertical_in_3d():
    cam = Camera(256, 256, hfov=50, horizon=40.0, cam_height=1.6)
    D1, rise, run, n = 3.0, 0.2, 0.4, 4
    h = hm.steps(cam, D1, rise, run, n)
    g = reconstruct_geometry(cam, h)
    ok = g.valid[:, 0] > 0
    Y = g.position[:, 0, 1][ok].astype(np.float64)
    D = g.depth[:, 0][ok].astype(np.float64)
    Dk = D1 + run * np.arange(n)
    on_tread = np.zeros(len(Y), bool)
    on_riser = np.zeros(len(Y), bool)
    for k in range(0, n + 1):
        lo = Dk[k - 1] if k >= 1 else 0.0
        hi = Dk[k] if k < n else np.inf
        on_tread |= (np.abs(Y - k * rise) < 1e-4) & (D >= lo - 1e-4) & (D <= hi + 1e-4)
    for k in range(1, n + 1):
        on_riser |= (np.abs(D - Dk[k - 1]) < 1e-4 * Dk[k - 1]) & (Y >= (k - 1) * rise - 1e-4) & (Y <= k * rise + 1e-4)
    assert np.all(on_tread | on_riser)
    assert on_riser.sum() >= 4 * 3 and on_tread.sum() > 20  # both kinds really visible
    # the brief's closed form on a tread: h = Y (v - horizon) / (H_cam - Y)
    v = np.arange(256)[ok] + 0.5
    tr = on_tread & (Y > 0.1)
    np.testing.assert_allclose(h[:, 0][ok][tr], (Y * (v - 40) / (1.6 - Y))[tr], rtol=1e-4)
    # every column is the same (the steps span the whole width)
    assert np.all(h == h[:, :1])


def test_curved_cove_floor_arc_wall_in_3d_and_continuous():
    cam = Camera(256, 256, hfov=50, horizon=40.0, cam_height=1.6)
    Dw, R = 4.0, 1.0
    h = hm.curved(cam, Dw, R)
    g = reconstruct_geometry(cam, h)
    ok = g.valid[:, 0] > 0
    Y = g.position[:, 0, 1][ok].astype(np.float64)
    D = g.depth[:, 0][ok].astype(np.float64)
    floor = (np.abs(Y) < 1e-5) & (D <= Dw - R + 1e-4)
    wall = (np.abs(D - Dw) < 1e-4) & (Y >= R - 1e-4)
    arc = np.abs(np.hypot(D - (Dw - R), Y - R) - R) < 1e-4
    assert np.all(floor | wall | arc)
    assert floor.sum() > 5 and wall.sum() > 5 and (arc & ~floor & ~wall).sum() > 5
    # smooth: no jump in h from row to row larger than the rows themselves move
    assert np.abs(np.diff(h[:, 0])).max() < 1.5
    # wall rows above the horizon are valid (the wall is in front of the camera)
    assert g.valid[0, 0] == 1


def test_background_node_kinds_shapes_and_steps_need_camera():
    cam = Camera(128, 96, hfov=50, horizon=20.0)
    for kind in hm.BACKGROUND_KINDS:
        out = BackgroundHeight().compute(Ctx(), Namespace({"camera": cam}),
                                         params_of(BackgroundHeight, kind=kind, corner=[64, 70],
                                                   corner2=[100, 70], junction_row=70))
        h = out["height"]
        assert h.shape == (96, 128) and h.dtype == np.float32 and np.all(np.isfinite(h))
        assert (h.max() == 0) == (kind == "ground")
    out = BackgroundHeight().compute(Ctx(), Namespace({"camera": cam}),
                                     params_of(BackgroundHeight, kind="back_wall",
                                               junction_points=[0, 60, 128, 80]))
    assert out["height"][10, 64] == pytest.approx(60 + 20 * 64.5 / 128 - 10.5, abs=1e-4)


def test_cutout_rectangle_on_row_v0():
    m = np.zeros((100, 80), np.float32)
    m[30:70, 20:50] = 1.0             # last row 69 -> contact at v0 = 70
    h = hm.contact_line_height(m)
    v = np.arange(100)[:, None] + 0.5
    np.testing.assert_allclose(h[30:70, 20:50], np.broadcast_to(70 - v[30:70], (40, 30)), atol=1e-5)
    assert np.all(h[m == 0] == 0)
    node = CutoutHeight().compute(Ctx(), Namespace({"mask": m}), params_of(CutoutHeight))
    np.testing.assert_array_equal(node["height"], h)


def test_contact_line_vs_column_bottom_on_raised_arm():
    m = np.zeros((100, 100), np.float32)
    m[20:80, 40:60] = 1.0   # body standing on v0 = 80
    m[30:36, 60:90] = 1.0   # arm held out to the right at rows 30..35
    line = hm.contact_line_height(m, "contact_line")
    col = hm.contact_line_height(m, "column_bottom")
    # the arm is high above the ground: its height is measured to the body's contact line
    assert line[33, 75] == pytest.approx(80 - 33.5, abs=1e-4)
    # per-column bottoms would put the arm on the ground
    assert col[33, 75] == pytest.approx(36 - 33.5, abs=1e-4)


def test_contact_line_fits_a_slanted_base():
    m = np.zeros((120, 100), np.float32)
    for c in range(30, 70):                 # bottom edge rises 1 px every 10 columns
        m[20:90 - (c - 30) // 10, c] = 1.0
    h = hm.contact_line_height(m, tolerance=5.0)
    # bottom edges 90 - (c-30)//10 (staircase); the fitted line has slope ~ -0.1
    assert h[50, 30] == pytest.approx(90 - 50.5, abs=0.6)
    assert h[50, 69] == pytest.approx(87 - 50.5, abs=0.6)


def test_predictor_protocol_and_empty_mask():
    p = hm.ContactLinePredictor()
    assert isinstance(p, hm.HeightPredictor)
    rgba = np.zeros((10, 10, 4), np.float32)
    assert np.all(p.predict(rgba) == 0)


def test_resize_pixel_height_multiplies_by_s():
    cam = Camera(64, 64, hfov=50, horizon=10)
    h = hm.back_wall(64, 64, row=40.0)
    h2 = hm.resize_pixel_height(h, 2.0)
    assert h2.shape == (128, 128)
    # the resized map is the template of the resized camera (junction row scaled by 2)
    np.testing.assert_allclose(h2, hm.back_wall(128, 128, row=80.0), atol=0.51)
    const = np.full((10, 20), 7.0, np.float32)
    np.testing.assert_allclose(hm.resize_pixel_height(const, 0.5), np.full((5, 10), 3.5), atol=1e-6)


def test_load_pixel_height_npy_exr_png16(tmp_path):
    import OpenImageIO as oiio
    h = (np.arange(12 * 16, dtype=np.float32).reshape(12, 16) * 0.5)
    np.save(tmp_path / "h.npy", h)
    np.testing.assert_array_equal(hm.load_pixel_height(tmp_path / "h.npy"), h)
    np.testing.assert_allclose(hm.load_pixel_height(tmp_path / "h.npy", 2.0), 2 * h)
    from pixgraph_nodes.ops.imageio import write_image
    write_image(tmp_path / "h.exr", h)
    np.testing.assert_allclose(hm.load_pixel_height(tmp_path / "h.exr"), h, rtol=1e-6)
    raw = np.round(h / h.max() * 65535).astype(np.uint16)
    out = oiio.ImageOutput.create(str(tmp_path / "h.png"))
    out.open(str(tmp_path / "h.png"), oiio.ImageSpec(16, 12, 1, oiio.UINT16))
    out.write_image(raw[:, :, None])
    out.close()
    got = hm.load_pixel_height(tmp_path / "h.png", scale=float(h.max()))
    np.testing.assert_allclose(got, h, atol=h.max() / 65535)


def test_camera_node_value_and_load_pixel_height_node(tmp_path):
    from pixgraph_nodes.camera import Camera as CameraNode
    from pixgraph_nodes.load_pixel_height import LoadPixelHeight

    cam = CameraNode().compute(Ctx(), Namespace({"image": None}), params_of(CameraNode, width=300, height=200, hfov=60.0,
                                                               horizon=-10.0, cam_height=1.7))["camera"]
    assert cam == Camera(300, 200, 60.0, -10.0, 1.7)
    assert cam.focal == pytest.approx(150.0 / math.tan(math.radians(30.0)))
    np.save(tmp_path / "bg.npy", np.full((4, 6), 2.5, np.float32))
    ctx = Ctx()
    ctx.graph_dir = str(tmp_path)
    out = LoadPixelHeight().compute(ctx, Namespace({}), params_of(LoadPixelHeight, path="bg.npy", scale=2.0))
    np.testing.assert_array_equal(out["height"], np.full((4, 6), 5.0, np.float32))
    assert LoadPixelHeight.spec.param("path").required
