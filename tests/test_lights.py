"""Lights in 3D and in pixel-height space."""
import math
import warnings

import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from pixgraph.node import Namespace
from pixgraph_nodes.light import Light as LightNode
from pixgraph_nodes.ops import lights as L
from pixgraph_nodes.ops.camera import Camera

CAM = Camera(512, 512, hfov=50.0, horizon=120.0, cam_height=1.0)
FOOT = np.array([0.3, 0.0, -4.0])


class Ctx:
    device = None
    graph_dir = None


def collinear_param(a, b, c):
    """t with a + t (c - a) = b in (u, v, h) space, and the residual distance."""
    a, b, c = (np.asarray(x, np.float64)[:3] for x in (a, b, c))
    d = c - a
    t = float(np.dot(b - a, d) / np.dot(d, d))
    return t, float(np.linalg.norm(a + t * d - b))


@pytest.mark.parametrize("az", [-150.0, -60.0, 0.0, 30.0, 90.0, 180.0])
@pytest.mark.parametrize("el", [5.0, 30.0, 60.0, 89.0])
def test_directional_light_point_lies_on_the_horizon(az, el):
    light = L.from_controls(FOOT, az, el)
    u, v, h, s = L.light_point(light, CAM)
    assert v + h == pytest.approx(CAM.horizon, abs=1e-3 * max(1.0, abs(float(h))))  # pytest >= 9.2: plain float
    d = np.array(light.direction)
    # light toward the camera side (d_z > 0) is behind the camera plane
    assert s == (-1.0 if d[2] > 0 else 1.0)


def test_point_light_projection_and_behind_camera_sign():
    p = L.point_light((1.0, 3.0, -5.0))
    u, v, h, s = L.light_point(p, CAM)
    uvh, D = CAM.project(np.array(p.position))
    np.testing.assert_allclose([u, v, h], uvh, rtol=1e-6)
    assert s == 1.0 and h == pytest.approx(CAM.focal * 3.0 / 5.0, rel=1e-6)
    behind = L.point_light((0.5, 2.0, 1.5))     # Z > 0: behind the camera plane
    u, v, h, s = L.light_point(behind, CAM)
    assert s == -1.0 and h < 0


@pytest.mark.parametrize("az,el,dist", [(30.0, 40.0, math.inf), (150.0, 25.0, math.inf),
                                         (0.0, 50.0, math.inf), (-70.0, 35.0, 3.0), (10.0, 60.0, 6.0)])
def test_pole_top_shadow_tip_and_light_are_collinear_in_uvh(az, el, dist):
    """A vertical pole of height Hp at FOOT: its shadow tip on the ground, the pole's
    top and the light point are on one straight line in (u, v, h) space (what the
    tracer marches), with the light beyond the top (s=+1) or behind the receiver (s=-1)."""
    Hp = 0.8
    light = L.from_controls(FOOT, az, el, dist)
    top = FOOT + [0, Hp, 0]
    if math.isinf(dist):
        d = np.array(light.direction)
    else:
        d = np.array(light.position) - top
    tip = top - d * (Hp / d[1])                 # where the ray from the light via the top meets Y=0
    (tip_uvh, _), (top_uvh, _) = CAM.project(tip), CAM.project(top)
    lp = L.light_point(light, CAM)
    t, res = collinear_param(tip_uvh, top_uvh, lp)
    assert res < 1e-3 * max(1.0, np.abs(lp[:3]).max() * 1e-3)
    if lp[3] > 0:
        assert 0 < t < 1          # the top lies between the tip and the light
    else:
        assert t < 0              # march away from the light's image point


def test_directional_shadow_length_closed_form():
    """Shadow of a pole of height Hp under a sun at elevation e along +X: the tip is at
    foot + Hp / tan(e) (away from the light); its image length follows the camera."""
    Hp, e = 0.5, 30.0
    light = L.from_controls(FOOT, -90.0, e)         # light to the left: shadow goes right (+X)
    d = np.array(light.direction)
    np.testing.assert_allclose(d, [-math.cos(math.radians(e)), math.sin(math.radians(e)), 0], atol=1e-12)
    tip = FOOT + np.array([Hp / math.tan(math.radians(e)), 0, 0])
    (foot_uvh, D), _ = CAM.project(FOOT), None
    tip_uvh, _ = CAM.project(tip)
    length = tip_uvh[0] - foot_uvh[0]
    assert length == pytest.approx(CAM.focal * Hp / math.tan(math.radians(e)) / 4.0, rel=1e-12)
    lp = L.light_point(light, CAM)
    t, res = collinear_param(tip_uvh, CAM.project(FOOT + [0, Hp, 0])[0], lp)
    # light parallel to the image plane: nudged off it by 1e-4, which moves the line by
    # far less than a pixel
    assert res < 0.01


def test_disk_samples_inside_projected_disk_mean_near_centre_deterministic():
    light = L.from_controls(FOOT, 40.0, 35.0, 3.0, kind="disk", radius=0.4)
    n = 64
    s = L.disk_samples(light, CAM, n, seed=0)
    assert s.shape == (n, 4) and s.dtype == np.float32
    np.testing.assert_array_equal(s, L.disk_samples(light, CAM, n, seed=0))
    assert not np.array_equal(s, L.disk_samples(light, CAM, n, seed=3))
    pts3 = L.sample_points_3d(light, n)
    c = np.array(light.position)
    nrm = np.array(light.normal)
    assert np.all(np.linalg.norm(pts3 - c, axis=1) <= 0.4 + 1e-9)
    assert np.abs((pts3 - c) @ nrm).max() < 1e-9               # on the disk's plane
    assert np.linalg.norm(pts3.mean(0) - c) < 0.02 * 0.4
    # inside the projected outline (a convex ellipse: the disk is in front of the camera)
    e1, e2 = L._disk_basis(nrm)
    a = np.linspace(0, 2 * np.pi, 721)
    rim = c + 0.4 * (np.cos(a)[:, None] * e1 + np.sin(a)[:, None] * e2)
    rim_uv = CAM.project(rim)[0][:, :2]
    assert MplPath(rim_uv).contains_points(s[:, :2].astype(np.float64), radius=1e-3).all() or \
        MplPath(rim_uv[::-1]).contains_points(s[:, :2].astype(np.float64), radius=-1e-3).all()
    centre = L.light_point(light, CAM)
    size = np.ptp(rim_uv, axis=0).max()
    assert np.linalg.norm(s[:, :2].mean(0) - centre[:2]) < 0.03 * size
    assert np.all(s[:, 3] == 1)


def test_disk_extremes_are_on_the_rim():
    light = L.from_controls(FOOT, 40.0, 35.0, 3.0, kind="disk", radius=0.4)
    ex = L.extreme_points_3d(light)
    c = np.array(light.position)
    np.testing.assert_allclose(np.linalg.norm(ex - c, axis=1), 0.4, rtol=1e-12)
    np.testing.assert_allclose(ex[0] + ex[1], 2 * c, atol=1e-12)  # opposite pairs
    np.testing.assert_allclose(ex[2] + ex[3], 2 * c, atol=1e-12)
    assert abs(np.dot(ex[0] - c, ex[2] - c)) < 1e-12
    assert abs(ex[0][1] - c[1]) < 1e-12      # e1 is horizontal: left/right extremes
    px = L.disk_extremes(light, CAM)
    assert px.shape == (4, 4) and np.all(np.isfinite(px))
    # a facing-down disk spans X and Z
    down = L.disk_light((0, 3, -4), 0.5, facing="down")
    exd = L.extreme_points_3d(down)
    np.testing.assert_allclose(exd[:, 1], 3.0)


def test_sun_disk_samples_are_in_the_cone():
    sun = L.from_controls(FOOT, 20.0, 40.0, angular_radius_deg=5.0)
    dirs = L.sample_points_3d(sun, 50)
    cosang = dirs @ np.array(sun.direction)
    assert np.all(cosang >= math.cos(math.radians(5.0)) - 1e-12)
    px = L.disk_samples(sun, CAM, 50)
    np.testing.assert_allclose(px[:, 1] + px[:, 2], CAM.horizon, atol=1e-2)  # all at infinity


@pytest.mark.parametrize("el", [0.0, -20.0, -90.0, 90.0, 89.9999])
@pytest.mark.parametrize("kind,dist", [("directional", math.inf), ("point", 3.0), ("disk", 3.0)])
def test_extreme_elevations_never_crash(el, kind, dist):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        light = L.from_controls(FOOT, 30.0, el, dist, kind=kind, radius=0.3, angular_radius_deg=2.0)
    if el <= 0:
        assert light.clamped and any("horizon" in str(x.message) for x in w)
        elev = math.degrees(math.asin((np.array(light.position) - FOOT)[1] / dist)) if kind != "directional" \
            else math.degrees(math.asin(light.direction[1]))
        assert elev == pytest.approx(L.MIN_ELEVATION_DEG, abs=1e-9)
    for arr in (L.light_point(light, CAM)[None], L.disk_samples(light, CAM, 16), L.disk_extremes(light, CAM)):
        assert np.all(np.isfinite(arr)) and set(np.unique(arr[:, 3])) <= {-1.0, 1.0}


@pytest.mark.parametrize("radius", [1e-9, 1e-4, 50.0, 1e4])
def test_huge_and_tiny_disks_stay_finite_and_above_ground(radius):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        light = L.from_controls(FOOT, 30.0, 20.0, 2.0, kind="disk", radius=radius)
        pts = L.sample_points_3d(light, 32)
        px = L.disk_samples(light, CAM, 32)
    assert np.all(pts[:, 1] > 0) and np.all(np.isfinite(px))
    if radius < 1e-3:
        np.testing.assert_allclose(px[:, :3], np.repeat(L.light_point(light, CAM)[None, :3], 32, 0), atol=0.05)


def test_light_exactly_in_camera_plane_is_nudged():
    p = L.point_light((1.0, 2.0, 0.0))             # D = 0
    lp = L.light_point(p, CAM)
    assert np.all(np.isfinite(lp)) and abs(lp[0]) > 1e5
    overhead = L.directional_light((0, 1, 0))
    lp = L.light_point(overhead, CAM)
    assert np.all(np.isfinite(lp)) and lp[1] + lp[2] == pytest.approx(CAM.horizon, rel=1e-6)


def test_from_shadow_tip_recovers_a_known_light():
    truth = L.from_controls(FOOT, -50.0, 35.0)
    Hp = 0.9
    top = FOOT + [0, Hp, 0]
    d = np.array(truth.direction)
    tip = top - d * (Hp / d[1])
    tip_uv = CAM.project(tip)[0][:2]
    top_uvh = CAM.project(top)[0]
    got = L.from_shadow_tip(CAM, tip_uv, top_uvh)
    np.testing.assert_allclose(got.direction, truth.direction, atol=1e-9)
    assert dict(got.controls)["azimuth"] == pytest.approx(-50.0)
    assert dict(got.controls)["elevation"] == pytest.approx(35.0)
    with pytest.raises(ValueError):
        L.from_shadow_tip(CAM, (100.0, 50.0), top_uvh)   # tip above the horizon
    pt = L.from_shadow_tip(CAM, tip_uv, top_uvh, distance=2.0, kind="point")
    np.testing.assert_allclose(pt.position, top + 2.0 * d, atol=1e-9)


def test_light_node_targets_the_mask_foot():
    mask = np.zeros((512, 512), np.float32)
    mask[200:400, 236:276] = 1.0                       # foot at (256, 400)
    params = Namespace(LightNode.spec.coerce_params({"kind": "point", "azimuth": 90.0,
                                                     "elevation": 45.0, "distance": 2.0}))
    light = LightNode().compute(Ctx(), Namespace({"camera": CAM, "mask": mask}), params)["light"]
    foot, _ = CAM.back_project(256.0, 400.0, 0.0)
    np.testing.assert_allclose(light.target, foot, atol=1e-12)
    np.testing.assert_allclose(np.array(light.position) - foot,
                               [2 * math.cos(math.pi / 4), 2 * math.sin(math.pi / 4), 0], atol=1e-12)
    with pytest.raises(ValueError, match="mask"):
        LightNode().compute(Ctx(), Namespace({"camera": CAM, "mask": None}), params)


def test_light_node_shadow_tip_placement():
    foot_uv = CAM.project(FOOT)[0][:2]
    top_uvh = CAM.project(FOOT + [0, 0.7, 0])[0]
    truth = L.from_controls(FOOT, 120.0, 40.0)
    d = np.array(truth.direction)
    tip_uv = CAM.project(FOOT + [0, 0.7, 0] - d * (0.7 / d[1]))[0][:2]
    params = Namespace(LightNode.spec.coerce_params({
        "kind": "directional", "placement": "shadow_tip", "tip_uv": [float(x) for x in tip_uv],
        "top_uvh": [float(x) for x in top_uvh]}))
    light = LightNode().compute(Ctx(), Namespace({"camera": CAM, "mask": None}), params)["light"]
    np.testing.assert_allclose(light.direction, truth.direction, atol=1e-9)
    assert light.kind == "directional" and foot_uv[1] > CAM.horizon
