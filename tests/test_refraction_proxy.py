"""Refraction at a proxy resolution (ops/refraction.py: ``rt_refract_hits`` traced at the
proxy, the hits' displacement enlarged edge-aware, colours looked up at full size)
against the full-resolution trace, plus the hit kernel against its numpy reference."""
import numpy as np
import pytest

from pixgraph_nodes.ops import refraction as RF
from pixgraph_nodes.ops.camera import Camera
from pixgraph_nodes.ops.sphere import sphere_cutout


def ball(N=384, smooth=True):
    """A glass ball on a floor before a back wall (the test_refraction scene, N px);
    ``smooth``: a background of slow sines (the hits' error shows as colour error
    without the sub-pixel aliasing of hard edges), else a checkerboard."""
    c = N / 96
    cam = Camera(N, N, hfov=50.0, horizon=20.0 * c)
    glass, gh = sphere_cutout(cam, N / 2, 80.0 * c, 0.12)
    u, v = cam.pixel_grid()
    if smooth:
        bg = np.stack([0.5 + 0.4 * np.sin(u / (5 * c)) * np.cos(v / (7 * c)), 0.5 + 0.4 * np.cos(u / (9 * c)),
                       v / N], -1).astype(np.float32)
    else:
        bg = np.repeat(((((np.floor(u / (6 * c)) + np.floor(v / (6 * c))) % 2) * 0.8 + 0.1)[..., None]), 3, -1)
        bg = bg.astype(np.float32)
    bgh = np.maximum(0.0, 40.0 * c - v).astype(np.float32)
    return cam, glass, gh, bg, bgh


@pytest.mark.parametrize("eta", [1.5, 1.0, 0.7])
@pytest.mark.parametrize("back", ["none", "local_sphere"])
def test_hit_kernel_matches_numpy(device, eta, back):
    cam, glass, gh, bg, bgh = ball(96, smooth=False)
    cl = RF.refraction_hits_cl(device, cam, glass, gh, bgh, eta=eta, back_surface=back)
    pos, wts = RF.refraction_hits_numpy(cam, glass, gh, bgh, eta=eta, back_surface=back)
    on = glass[..., 3] > 0
    assert on.sum() > 150
    d = np.abs(cl["pos"] - pos).max(-1)
    assert (d > 1e-2).sum() <= 2 and d.max() < 1.0          # measured: max 1e-3 px
    np.testing.assert_allclose(cl["wts"], wts, atol=1e-4)
    u, v = cam.pixel_grid()
    np.testing.assert_array_equal(cl["pos"][~on][:, 0], (u[~on]).astype(np.float32))   # off the glass: own centre


def test_hits_give_the_colours_of_the_full_trace(device):
    """The hit positions, looked up bilinearly at full size, give refraction_cl's
    colours up to the sub-pixel difference of crossing point and hit pixel."""
    cam, glass, gh, bg, bgh = ball(384)
    full = RF.refraction_cl(device, cam, glass, gh, bg, bgh, eta=1.5)["layer"]
    h = RF.refraction_hits_cl(device, cam, glass, gh, bgh, eta=1.5)
    yy, xx = np.nonzero(glass[..., 3] > 0)
    col = (h["wts"][yy, xx, :1] * RF._bilinear(bg, h["pos"][yy, xx, 0], h["pos"][yy, xx, 1])
           + h["wts"][yy, xx, 1:] * RF._bilinear(bg, h["pos"][yy, xx, 2], h["pos"][yy, xx, 3]))
    err = glass[yy, xx, 3, None] * col - full[yy, xx, :3]
    assert float(np.sqrt(np.mean(err ** 2))) < 0.008          # measured 0.0036


def test_eta_one_through_the_proxy_is_the_background_exactly(device):
    """Analytic: with eta = 1 no ray bends, every hit is the pixel itself, so the
    proxy's enlarged displacement is 0 and the layer is alpha * background."""
    cam, glass, gh, bg, bgh = ball(384, smooth=False)
    for back in ("none", "local_sphere"):
        r = RF.refraction_proxy(device, cam, glass, gh, bg, bgh, eta=1.0, back_surface=back, max_side=96)
        assert r["proxy"] == (96, 96)
        a = glass[..., 3:]
        np.testing.assert_allclose(r["layer"][..., :3], a * bg, atol=1e-6)
        np.testing.assert_array_equal(r["layer"][..., 3], glass[..., 3])


# measured (384 px, proxy 192): interior RMSE 0.0037 / 0.015, all glass 0.026 / 0.034 (the
# full-resolution hits looked up the same way differ from refraction_cl by 0.0036)
@pytest.mark.parametrize("back,inner_bound,bound", [("none", 0.008, 0.05), ("local_sphere", 0.03, 0.06)])
def test_proxy_against_the_full_trace(device, back, inner_bound, bound):
    cam, glass, gh, bg, bgh = ball(384)
    full = RF.refraction_cl(device, cam, glass, gh, bg, bgh, eta=1.5, back_surface=back)["layer"]
    r = RF.refraction_proxy(device, cam, glass, gh, bg, bgh, eta=1.5, back_surface=back, max_side=192)
    assert r["proxy"] == (192, 192) and r["layer"].shape == full.shape
    on = glass[..., 3] > 0
    assert np.array_equal(r["layer"][~on], full[~on])                 # nothing outside the glass
    err = r["layer"] - full
    rmse = float(np.sqrt(np.mean(err[on] ** 2)))
    # the interior: 6 px (3 proxy px) and more inside the outline
    inner = on.copy()
    for _ in range(6):
        inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
    inner_rmse = float(np.sqrt(np.mean(err[inner] ** 2)))
    assert inner.sum() > 0.5 * on.sum()
    assert inner_rmse < inner_bound
    assert rmse < bound                # the rim, where the displacement grows fastest
    assert r["hit"][on].mean() > 0.9


def test_no_proxy_at_or_below_its_size(device):
    cam, glass, gh, bg, bgh = ball(96, smooth=False)
    want = RF.refraction_cl(device, cam, glass, gh, bg, bgh, eta=1.5)["layer"]
    r = RF.refraction_proxy(device, cam, glass, gh, bg, bgh, eta=1.5, max_side=96)
    assert np.array_equal(r["layer"], want) and r["proxy"] == (96, 96)
    with pytest.raises(ValueError, match="at least 16"):
        RF.refraction_proxy(device, cam, glass, gh, bg, bgh, max_side=8)
