"""Analytic shadows: a vertical pole under a directional light, on the ground and on a
back wall, traced by the hard-shadow kernel with lights converted by ops.lights."""
import math

import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from pixgraph.node import Namespace
from pixgraph_nodes.hard_shadow import HardShadow
from pixgraph_nodes.ops import heightmaps as hm
from pixgraph_nodes.ops import lights as L
from pixgraph_nodes.ops.camera import Camera

CAM = Camera(512, 512, hfov=50.0, horizon=120.0, cam_height=1.0)
DF, HP, WIDTH = 3.0, 0.6, 0.04           # pole: depth, height, width [world units]
FOOT = np.array([0.0, 0.0, -DF])


class Ctx:
    def __init__(self, device, scale=1.0):
        self.device = device
        self.graph_dir = None
        self.scale = scale

    def progress(self, fraction, message=""):
        pass

    def check_cancelled(self):
        pass

    def log(self, message):
        pass


def pole():
    """Mask and pixel height of a thin upright pole (a billboard facing the camera)."""
    f = CAM.focal
    uf, vf, _ = CAM.project(FOOT)[0]
    u, v = CAM.pixel_grid()
    inside = (np.abs(u - uf) < f * WIDTH / 2 / DF) & (v < vf) & (v > vf - f * HP / DF)
    return inside.astype(np.float32), np.where(inside, vf - v, 0.0).astype(np.float32)


def shadow(device, bg, light):
    mask, fg = pole()
    ins = Namespace({"mask": mask, "fg_height": fg, "bg_height": bg, "light": light, "camera": CAM})
    out = HardShadow().compute(Ctx(device), ins, Namespace(HardShadow.spec.coerce_params({})))
    np.testing.assert_array_equal(out["darkness"], 1 - out["lit"])
    return out["lit"]


@pytest.mark.parametrize("az,el", [(-60.0, 30.0), (-60.0, 50.0), (130.0, 40.0), (40.0, 25.0)])
def test_pole_shadow_length_on_ground_matches_closed_form(device, az, el):
    light = L.from_controls(FOOT, az, el)
    lit = shadow(device, np.zeros((512, 512), np.float32), light)
    # closed form: tip = foot + HP / tan(el) along the horizontal direction away from the light
    away = -np.array([math.sin(math.radians(az)), 0.0, math.cos(math.radians(az))])
    tip = FOOT + HP / math.tan(math.radians(el)) * away
    foot_uv = CAM.project(FOOT)[0][:2]
    tip_uv = CAM.project(tip)[0][:2]
    length = float(np.linalg.norm(tip_uv - foot_uv))
    assert length > 40.0
    dirn = (tip_uv - foot_uv) / length
    # the pole is a WIDTH-wide billboard: its ground shadow is the quadrilateral of the
    # shadows of its 4 corners, and its far end along the shadow direction is the
    # shadow of a top corner (the centre tip plus or minus half the width in X)
    half = np.array([WIDTH / 2, 0.0, 0.0])
    corners = [FOOT - half, FOOT + half, tip + half, tip - half]
    quad = np.array([CAM.project(c)[0][:2] for c in corners])
    far = max(float((q - foot_uv) @ dirn) for q in quad[2:])
    assert abs(far - length) < 6.0                       # the corners are near the centre tip
    mask, _ = pole()
    u, v = CAM.pixel_grid()
    ground = (mask == 0) & (v > CAM.project(FOOT)[0][1] - 0.5 * length)
    sh = (lit < 0.5) & (mask == 0)
    along = (u - foot_uv[0]) * dirn[0] + (v - foot_uv[1]) * dirn[1]
    measured = along[sh].max()
    assert measured == pytest.approx(far, abs=1.5)
    # and the shadowed pixels are the projected quadrilateral, up to a one-pixel rim
    inside = MplPath(quad).contains_points(np.stack([u.ravel(), v.ravel()], 1)).reshape(u.shape)
    inside &= mask == 0
    near = inside.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            near |= np.roll(np.roll(inside, dy, 0), dx, 1)
    assert (inside & sh).sum() / inside.sum() > 0.9
    assert (near & sh).sum() / sh.sum() > 0.97


def test_pole_shadow_turns_up_the_back_wall_at_the_junction(device):
    DW = 3.6
    junction = CAM.project(np.array([0.0, 0.0, -DW]))[0][1]
    bg = hm.back_wall(512, 512, row=junction)
    light = L.from_controls(FOOT, 20.0, 20.0)
    lit = shadow(device, bg, light)
    # 3D: the ray from the pole's top away from the light meets the wall plane Z = -DW
    d = np.array(light.direction)
    top = FOOT + [0.0, HP, 0.0]
    hit = top - (DW - DF) / d[2] * d
    assert 0.1 < hit[1] < HP                   # the shadow really climbs the wall
    u_hit, v_hit, h_hit = CAM.project(hit)[0]
    assert v_hit + h_hit == pytest.approx(junction, abs=1e-6)   # its foot is on the junction
    col = lit[:, int(u_hit)] < 0.5
    rows = np.nonzero(col)[0] + 0.5
    # the wall shadow is a vertical segment from the junction up to the projected hit
    assert rows.min() == pytest.approx(v_hit, abs=1.5)
    assert rows.max() >= junction - 1.0
    on_wall = rows[rows < junction]
    assert len(on_wall) == pytest.approx(junction - v_hit, abs=2.0)
    assert np.all(np.diff(on_wall) == 1.0)
    # with the ground only, the same light casts the shadow past the junction row instead
    lit_g = shadow(device, np.zeros((512, 512), np.float32), light)
    assert lit_g[int(v_hit) + 5, int(u_hit)] > 0.5


def _inputs(bg, light):
    mask, fg = pole()
    return Namespace({"mask": mask, "fg_height": fg, "bg_height": bg, "light": light, "camera": CAM})


def test_soft_shadow_node_point_light_is_hard_and_disk_widens_penumbra(device):
    from pixgraph_nodes.soft_shadow import SoftShadow

    bg = np.zeros((512, 512), np.float32)
    pt = L.from_controls(FOOT, -60.0, 35.0, 3.0, kind="point")
    hard = shadow(device, bg, pt)
    par = Namespace(SoftShadow.spec.coerce_params({"samples": 32}))
    soft = SoftShadow().compute(Ctx(device), _inputs(bg, pt), par)["lit"]
    np.testing.assert_array_equal(soft, hard)
    partial = []
    for r in (0.05, 0.25):
        disk = L.from_controls(FOOT, -60.0, 35.0, 3.0, kind="disk", radius=r)
        s = SoftShadow().compute(Ctx(device), _inputs(bg, disk), par)["lit"]
        assert s.min() >= 0 and s.max() <= 1
        partial.append(int(((s > 0.02) & (s < 0.98)).sum()))
    assert partial[1] > 1.5 * partial[0] > 0   # bigger light, wider penumbra


def test_buffer_channels_node_hard_channel_matches_hard_shadow(device):
    from pixgraph_nodes.buffer_channels import BufferChannels

    DW = 3.6
    bg = hm.back_wall(512, 512, row=CAM.project(np.array([0.0, 0.0, -DW]))[0][1])
    disk = L.from_controls(FOOT, 20.0, 25.0, 4.0, kind="disk", radius=0.3)
    out = BufferChannels().compute(Ctx(device), _inputs(bg, disk),
                                   Namespace(BufferChannels.spec.coerce_params({})))["buffers"]
    np.testing.assert_array_equal(out["hard_shadow"], 1 - shadow(device, bg, disk))
    sparse = [out[f"sparse_hard_shadow_{i}"] for i in range(4)]
    # the 4 extreme points cast 4 different shadows around the centre's
    assert len({s.tobytes() for s in sparse}) == 4
    union = np.maximum.reduce(sparse)
    assert union.sum() >= out["hard_shadow"].sum()


def test_merged_cutouts_cast_on_each_other(device):
    from pixgraph_nodes.merge_cutouts import MergeCutouts

    def billboard(depth, x, height, width):
        f = CAM.focal
        uf, vf, _ = CAM.project(np.array([x, 0.0, -depth]))[0]
        u, v = CAM.pixel_grid()
        m = (np.abs(u - uf) < f * width / 2 / depth) & (v < vf) & (v > vf - f * height / depth)
        return m.astype(np.float32), np.where(m, vf - v, 0.0).astype(np.float32)

    front_m, front_h = billboard(3.0, 0.0, 0.6, 0.08)
    back_m, back_h = billboard(3.6, 0.0, 0.5, 0.8)       # a wide panel right behind it
    img = lambda m: np.repeat(m[:, :, None], 3, axis=2)
    merged = MergeCutouts().compute(Ctx(device), Namespace({
        "mask_a": front_m, "height_a": front_h, "image_a": img(front_m),
        "mask_b": back_m, "height_b": back_h, "image_b": img(back_m)}), Namespace({}))
    light = L.from_controls(np.array([0.0, 0.0, -3.0]), 20.0, 30.0)  # from the camera side, right
    ins = Namespace({"mask": merged["mask"], "fg_height": merged["height"],
                     "bg_height": np.zeros((512, 512), np.float32), "light": light, "camera": CAM})
    lit = HardShadow().compute(Ctx(device), ins, Namespace(HardShadow.spec.coerce_params({})))["lit"]
    only_back = (back_m > 0) & (front_m == 0)
    # the front pole's shadow lands on the back panel (it climbs it, like a wall): the
    # band its top edge casts, computed in 3D and projected
    sh = (lit < 0.5) & only_back
    assert sh.sum() > 100
    d = np.array(light.direction)
    top = np.array([0.0, 0.6, -3.0])
    hit = top - (3.6 - 3.0) / d[2] * d                  # top centre's shadow on the panel
    u_hit, v_hit, _ = CAM.project(hit)[0]
    half = CAM.focal * 0.04 / 3.6                        # the pole's half width on the panel
    u, v = CAM.pixel_grid()
    foot_row = CAM.project(np.array([0, 0, -3.6]))[0][1]
    band = (np.abs(u - u_hit) < half - 1.5) & only_back & (v > v_hit + 1.5) & (v < foot_row - 1.5)
    assert band.sum() > 200 and np.all(sh[band])   # the true shadow band is fully dark
    # (and no spurious extra shadow next to it: see the test below)
    # without the front pole the back panel is fully lit from the front
    ins2 = Namespace({"mask": back_m, "fg_height": back_h, "bg_height": np.zeros((512, 512), np.float32),
                      "light": light, "camera": CAM})
    lit2 = HardShadow().compute(Ctx(device), ins2, Namespace(HardShadow.spec.coerce_params({})))["lit"]
    assert (lit2[only_back] < 0.5).sum() == 0


def test_merged_cutouts_no_shadow_outside_the_true_band(device):
    f = CAM.focal
    u, v = CAM.pixel_grid()

    def billboard(depth, height, width):
        vf = CAM.project(np.array([0.0, 0.0, -depth]))[0][1]
        m = (np.abs(u - 256) < f * width / 2 / depth) & (v < vf) & (v > vf - f * height / depth)
        return m.astype(np.float32), np.where(m, vf - v, 0.0).astype(np.float32)

    from pixgraph_nodes.ops.cutouts import merge_cutouts
    fm, fh = billboard(3.0, 0.6, 0.08)
    bm, bh = billboard(3.6, 0.5, 0.8)
    m, h, _ = merge_cutouts([fm, bm], [fh, bh])
    light = L.from_controls(np.array([0.0, 0.0, -3.0]), 20.0, 30.0)
    ins = Namespace({"mask": m, "fg_height": h, "bg_height": np.zeros((512, 512), np.float32),
                     "light": light, "camera": CAM})
    lit = HardShadow().compute(Ctx(device), ins, Namespace(HardShadow.spec.coerce_params({})))["lit"]
    d = np.array(light.direction)
    hit = np.array([0.0, 0.6, -3.0]) - 0.6 / d[2] * d
    u_hit, v_hit, _ = CAM.project(hit)[0]
    half = f * 0.04 / 3.6
    true_band = (np.abs(u - u_hit) < half + 1.5) & (v > v_hit - 1.5)
    wrong = (lit < 0.5) & (bm > 0) & (fm == 0) & ~true_band
    assert wrong.sum() == 0, wrong.sum()
