"""SSN++ buffer channels: layout, consistency with the shadow tracer, and the
relative distance against the closed form for a pole."""
import numpy as np
import pytest

import _shadow_scenes as sc
from pixgraph_nodes.ops import buffers as B
from pixgraph_nodes.ops import shadow as S

H = W = 160
POLE = dict(u_left=63, width=3, top=60, bottom=100)
LIGHT = np.array([4.0, 130.0 - 80.0, 80.0, 1.0])     # in front of the pole, to the left
R = 10.0
EXTREMES = np.array([LIGHT + [R, 0, 0, 0], LIGHT - [R, 0, 0, 0], LIGHT + [0, 0, R, 0], LIGHT - [0, 0, R, 0]])


@pytest.fixture(scope="module")
def pole_scene():
    mask, fg = sc.pole(H, W, **POLE)
    bg = sc.wall_bg(H, W, 30.0)        # ground + a wall far behind (junction row 30)
    return mask, fg, bg


@pytest.fixture(scope="module")
def pole_channels(device, pole_scene):
    return B.buffer_channels(device, *pole_scene, LIGHT, EXTREMES)


def test_keys_shapes_and_order(device, pole_scene, pole_channels):
    assert tuple(pole_channels) == B.CHANNELS
    assert B.CHANNELS[3] == "hard_shadow" and B.CHANNELS[-1] == "relative_distance"
    for k, v in pole_channels.items():
        assert v.shape == (H, W) and v.dtype == np.float32, k
        assert np.all(np.isfinite(v)), k
    st = B.stack(pole_channels)
    assert st.shape == (len(B.CHANNELS), H, W)


def test_matches_reference(pole_scene, pole_channels):
    ref = B.buffer_channels_ref(*pole_scene, LIGHT, EXTREMES)
    for k in B.CHANNELS:
        if k == "relative_distance":
            assert np.allclose(pole_channels[k], ref[k], atol=1e-3), k
        else:
            assert np.mean(pole_channels[k] != ref[k]) <= 0.01, k


def test_simple_channels(pole_scene, pole_channels):
    mask, fg, bg = pole_scene
    assert np.array_equal(pole_channels["cutout_height"], np.where(mask > 0.5, fg, 0))
    # wall: h = max(0, 30 - v) -> dh/dv = -1 on the wall, 0 on the ground, 0 along u
    gy = pole_channels["bg_gradient_y"]
    assert np.allclose(gy[5:25], -1.0) and np.allclose(gy[40:], 0.0)
    assert np.allclose(pole_channels["bg_gradient_x"], 0.0)
    # h at rows 28..31 = 1.5, 0.5, 0, 0: central differences at the kink
    assert np.allclose(gy[29:31, 0], [-0.75, -0.25])


def test_hard_shadow_channel_is_darkness(device, pole_scene, pole_channels):
    lit = S.hard_shadow(device, *pole_scene, LIGHT)
    assert np.array_equal(pole_channels["hard_shadow"], 1.0 - lit)
    assert pole_channels["hard_shadow"].sum() > 30


def test_sparse_shadows_bound_the_penumbra(device, pole_scene, pole_channels):
    mask = pole_scene[0]
    centre = pole_channels["hard_shadow"] > 0.5
    sparse = [pole_channels[f"sparse_hard_shadow_{e}"] > 0.5 for e in range(4)]
    for e in range(4):
        assert np.array_equal(sparse[e], S.hard_shadow(device, *pole_scene, EXTREMES[e]) == 0)
        assert (sparse[e] != centre).sum() > 5, e
    # a lower light (extreme 3) throws a longer shadow, a higher one (2) a shorter one
    ground = mask < 0.5
    assert (sparse[3] & ground).sum() > (centre & ground).sum() > (sparse[2] & ground).sum()
    # moving the light right (+u) moves the shadow left: compare mean u of the shadows
    mean_u = lambda s: np.nonzero(s & ground)[1].mean()
    assert mean_u(sparse[0]) < mean_u(centre) < mean_u(sparse[1])
    # extremes at the centre give back the centre shadow
    same = B.buffer_channels(device, *pole_scene, LIGHT, np.array([LIGHT] * 4))
    for e in range(4):
        assert np.array_equal(same[f"sparse_hard_shadow_{e}"], same["hard_shadow"])


def test_relative_distance_of_the_pole(pole_scene, pole_channels):
    """The ray from a shadowed ground receiver r = (u, v, 0) to the light L crosses
    the pole, the plane v + h = bottom + 0.5, at t = (bottom + 0.5 - v) /
    (L.v + L.h - v); the occluder point is r + t (L - r), at distance t |L - r|."""
    mask, fg, bg = pole_scene
    dist = pole_channels["relative_distance"]
    dark = pole_channels["hard_shadow"] > 0.5
    assert np.all(dist[~dark] == 0.0)
    assert np.all(dist[dark] > 0.0)
    ground = dark & (mask < 0.5) & (bg == 0)
    ii, jj = np.nonzero(ground)
    assert ii.size > 30
    ru, rv = jj + 0.5, ii + 0.5
    Lu, Lv, Lh = LIGHT[:3]
    t = (POLE["bottom"] + 0.5 - rv) / (Lv + Lh - rv)
    analytic = t * np.sqrt((Lu - ru) ** 2 + (Lv - rv) ** 2 + Lh ** 2)
    err = dist[ii, jj] - analytic
    # the first blocking sample lies within about one march step (~1.4 px in
    # (u, v, h) here) plus the thickness of the crossing
    assert np.median(np.abs(err)) <= 1.5, np.median(np.abs(err))
    assert np.abs(err).max() <= 4.0, np.abs(err).max()
    # farther from the pole -> larger distance (softer shadow)
    far = analytic > np.median(analytic)
    assert dist[ii, jj][far].mean() > 1.5 * dist[ii, jj][~far].mean()
