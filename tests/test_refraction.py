"""Refraction through a transparent cutout: Snell, total internal reflection,
eta = 1, numpy reference vs OpenCL, the procedural sphere's pixel height."""
import math

import numpy as np
import pytest

from pixgraph_nodes.ops import reflection as R
from pixgraph_nodes.ops.camera import Camera, reconstruct
from pixgraph_nodes.ops.sphere import sphere_cutout


def ball_scene(W=96, H=96, wall=True):
    """A glass ball on a checkered floor in front of a striped back wall."""
    cam = Camera(W, H, hfov=50.0, horizon=20.0)
    glass, gh = sphere_cutout(cam, 48.0, 80.0, 0.12)
    u, v = cam.pixel_grid()
    bg = np.zeros((H, W, 3), np.float32)
    bg[...] = (((np.floor(u / 6) + np.floor(v / 6)) % 2) * 0.8 + 0.1)[..., None]
    bg[..., 0] *= (u / W).astype(np.float32)
    bgh = np.zeros((H, W), np.float32)
    if wall:
        bgh = np.maximum(0.0, 40.0 - v).astype(np.float32)        # a back wall standing on row 40
        bg[v < 40, 1] = ((u[v < 40] // 4) % 2) * 0.9
    return cam, glass, gh, bg, bgh


def test_snell_law_and_unit_directions():
    rng = np.random.default_rng(0)
    n = np.tile([0.0, 0.0, 1.0], (1000, 1))
    view = rng.normal(size=(1000, 3))
    view[:, 2] = -np.abs(view[:, 2])
    view /= np.linalg.norm(view, axis=1, keepdims=True)
    for eta in (1.33, 1.5, 0.8):
        d, tir = R.refract(view, n, eta)
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-12)
        sin_i = np.linalg.norm(np.cross(view, n), axis=1)
        sin_t = np.linalg.norm(np.cross(d, n), axis=1)
        ok = ~tir
        np.testing.assert_allclose(sin_i[ok], eta * sin_t[ok], atol=1e-9)       # n1 sin_i = n2 sin_t
        assert np.all(d[ok, 2] < 0)                                             # goes through
        np.testing.assert_array_equal(tir, sin_i > eta)                         # TIR past the critical angle
        assert np.all(d[tir, 2] > 0)                                            # reflected back
        # the plane of incidence is kept
        np.testing.assert_allclose(np.einsum("ij,ij->i", np.cross(view, n), d), 0.0, atol=1e-9)


@pytest.mark.parametrize("wall", [False, True])
def test_eta_one_displaces_nothing(device, wall):
    cam, glass, gh, bg, bgh = ball_scene(wall=wall)
    r = R.refraction_cl(device, cam, glass, gh, bg, bgh, eta=1.0)
    a = glass[..., 3:]
    np.testing.assert_array_equal(r["layer"][..., :3], a * bg)
    np.testing.assert_array_equal(r["layer"][..., 3], glass[..., 3])
    assert not r["tir"].any()


def test_refraction_moves_the_background(device):
    cam, glass, gh, bg, bgh = ball_scene()
    r = R.refraction_cl(device, cam, glass, gh, bg, bgh, eta=1.5)
    inside = glass[..., 3] == 1
    moved = np.abs(r["layer"][..., :3] - bg).max(-1) > 0.05
    assert moved[inside].mean() > 0.3


@pytest.mark.parametrize("eta", [1.5, 1.33, 0.7, 0.4])
@pytest.mark.parametrize("hiz", [True, False])
def test_numpy_and_opencl_agree(device, eta, hiz):
    cam, glass, gh, bg, bgh = ball_scene()
    cl = R.refraction_cl(device, cam, glass, gh, bg, bgh, eta=eta, hiz=hiz)
    ref, tir = R.refraction_numpy(cam, glass, gh, bg, bgh, eta=eta)
    bad = np.abs(cl["layer"] - ref).max(-1) > 1e-4
    assert bad.sum() <= 2, np.argwhere(bad)
    assert (cl["tir"] != tir).sum() <= 1


@pytest.mark.parametrize("eta", [0.7, 0.4, 0.1])
def test_total_internal_reflection_stays_finite(device, eta):
    """An object optically thinner than its surroundings (an air bubble): past the
    critical angle all light is reflected; the output stays finite and bounded."""
    cam, glass, gh, bg, bgh = ball_scene()
    for fresnel in (True, False):
        r = R.refraction_cl(device, cam, glass, gh, bg, bgh, eta=eta, fresnel=fresnel)
        assert np.isfinite(r["layer"]).all()
        assert r["layer"][..., :3].max() <= bg.max() + 1e-6
        geo = reconstruct(cam, gh)
        cos_i = np.abs(np.sum(R.view_directions(cam) * geo["normal"], -1))
        expect = (1.0 - (1.0 - cos_i ** 2) / eta ** 2 < 0) & (glass[..., 3] > 0) & (geo["valid"] > 0)
        assert r["tir"].any()
        assert (r["tir"] != expect).sum() <= 2
    # grazing: the silhouette of the ball is in total internal reflection first
    assert r["tir"][glass[..., 3] > 0].mean() > 0.05


def test_sphere_pixel_height_reconstructs_the_sphere():
    cam = Camera(128, 96, hfov=55.0, horizon=25.0, cam_height=1.4)
    glass, gh = sphere_cutout(cam, 70.0, 80.0, 0.2)
    (G,), _ = cam.back_project([70.0], [80.0], [0.0])
    centre = np.array([G[0], 0.2, G[2]])
    full = glass[..., 3] == 1
    geo = reconstruct(cam, gh)
    P = geo["position"][full].astype(np.float64)
    np.testing.assert_allclose(np.linalg.norm(P - centre, axis=1), 0.2, rtol=2e-4)
    # the normals point out of the sphere (toward the camera side)
    inner = full & np.roll(full, 1, 0) & np.roll(full, -1, 0) & np.roll(full, 1, 1) & np.roll(full, -1, 1)
    nrm = geo["normal"][inner].astype(np.float64)
    radial = (geo["position"][inner] - centre) / 0.2
    assert np.mean(np.sum(nrm * radial, 1)) > 0.99
    assert gh[full].min() > 0 and glass[..., 3].sum() > 100
    with pytest.raises(ValueError):
        sphere_cutout(cam, 70.0, 10.0, 0.2)          # contact point above the horizon


def test_local_sphere_radius_of_a_ball():
    cam, glass, gh, bg, bgh = ball_scene()
    R_ = R.local_radius(reconstruct(cam, gh), glass[..., 3])
    full = glass[..., 3] == 1
    assert np.median(R_[full]) == pytest.approx(0.12, rel=0.05)
    assert np.all(R_[full] > 0) and np.all(R_[glass[..., 3] == 0] == 0)
    # a flat cutout has no finite radius: one interface only
    card = np.zeros_like(full)
    card[40:70, 30:60] = True
    v = np.arange(96)[:, None] + 0.5
    flat = np.where(card, 75.0 - v, 0.0).astype(np.float32)    # an upright card facing the camera
    assert np.all(R.local_radius(reconstruct(cam, flat), card.astype(np.float32), max_radius=1e3) == 0)


@pytest.mark.parametrize("eta", [1.0, 1.5, 0.7])
def test_back_surface_numpy_and_opencl_agree(device, eta):
    cam, glass, gh, bg, bgh = ball_scene()
    cl = R.refraction_cl(device, cam, glass, gh, bg, bgh, eta=eta, back_surface="local_sphere")
    ref, _ = R.refraction_numpy(cam, glass, gh, bg, bgh, eta=eta, back_surface="local_sphere")
    assert (np.abs(cl["layer"] - ref).max(-1) > 1e-4).sum() <= 2
    assert np.isfinite(cl["layer"]).all()
    if eta == 1.0:
        np.testing.assert_array_equal(cl["layer"][..., :3], glass[..., 3:] * bg)


def test_ball_inverts_the_image_behind_it(device):
    """A solid glass ball is a lens: the wall (above the floor behind it) shows in
    the ball's lower half and the floor in its upper half; with one interface the
    order stays upright."""
    cam, glass, gh, bg, bgh = ball_scene()
    full = glass[..., 3] == 1
    rows = np.nonzero(full.any(1))[0]
    top, bottom = rows[: len(rows) // 3], rows[-len(rows) // 3:]
    wall_green = lambda L, rr: np.mean(L[rr][full[rr]][:, 1] - L[rr][full[rr]][:, 0])
    two = R.refraction_cl(device, cam, glass, gh, bg, bgh, eta=1.5, fresnel=False, back_surface="local_sphere")["layer"]
    one = R.refraction_cl(device, cam, glass, gh, bg, bgh, eta=1.5, fresnel=False, back_surface="none")["layer"]
    # the floor is grey (r = g up to the red ramp), the wall stripes green
    assert wall_green(two, bottom) > wall_green(two, top)
    assert wall_green(one, bottom) <= wall_green(one, top)


@pytest.mark.parametrize("case", ["border", "nan_glass", "nan_bg", "tiny"])
def test_refraction_stays_finite_in_hard_cases(device, case):
    cam, glass, gh, bg, bgh = ball_scene()
    if case == "border":
        glass, gh = sphere_cutout(cam, 2.0, 94.0, 0.2)      # cut by the left and bottom edges
    elif case == "nan_glass":
        gh = gh.copy()
        gh[70:72, 45:50] = np.nan
    elif case == "nan_bg":
        bgh = bgh.copy()
        bgh[60:70, 40:60] = np.nan
    elif case == "tiny":
        glass, gh = sphere_cutout(cam, 48.0, 80.0, 0.004)   # about a pixel
    for back in ("none", "local_sphere"):
        r = R.refraction_cl(device, cam, glass, gh, bg, bgh, eta=1.5, back_surface=back)
        L = r["layer"]
        assert np.isfinite(L).all()
        assert L.min() >= 0 and np.all(L[..., :3] <= L[..., 3:] * bg.max() + 1e-6)
        assert np.all(L[glass[..., 3] == 0] == 0)
