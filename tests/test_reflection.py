"""Reflection traced in pixel-height space: planar mirror closed form, Fresnel, GGX
sampling, numpy reference vs OpenCL, Hi-Z vs plain marching, adaptive sampling."""
import math

import numpy as np
import pytest

from pixgraph_nodes.ops import march
from pixgraph_nodes.ops import reflection as R
from pixgraph_nodes.ops.camera import Camera


def upright_scene(W=64, H=64, horizon=8.0, foot=40.25, rows=(20, 40), cols=(20, 44), seed=1):
    """A vertical rectangle facing the camera standing on a flat ground: pixel height
    = distance to its foot row ``foot`` (a half-way foot keeps every hit test clear
    of float ties). Each cutout pixel has its own random colour."""
    cam = Camera(W, H, hfov=50.0, horizon=horizon)
    rng = np.random.default_rng(seed)
    cut = np.zeros((H, W, 4), np.float32)
    r0, r1 = rows
    c0, c1 = cols
    cut[r0:r1, c0:c1, :3] = rng.uniform(0.05, 1.0, (r1 - r0, c1 - c0, 3))
    cut[r0:r1, c0:c1, 3] = 1.0
    fg = np.zeros((H, W), np.float32)
    fg[r0:r1, c0:c1] = foot - (np.arange(r0, r1)[:, None] + 0.5)
    return cam, cut, fg, np.zeros((H, W), np.float32)


def mirror_fresnel(cam, eta):
    cos_o = np.clip(-R.view_directions(cam)[..., 1], 0.0, 1.0)   # ground normal +Y
    return R.fresnel_dielectric(cos_o, eta)


def test_mirror_floor_flips_about_foot_line(device):
    cam, cut, fg, bg = upright_scene()
    r = R.reflection_cl(device, cam, cut, fg, bg, roughness=0.0, eta=1.5, planar=False)
    layer = r["layer"]
    # the cutout row q (centre q + .5) appears at row 2 * 40.25 - (q + .5) - .5 = 80 - q - 1
    F = mirror_fresnel(cam, 1.5)
    rows = np.arange(40, 60)
    expected = cut[79 - rows] * F[40:60, :, None]
    np.testing.assert_allclose(layer[40:60], expected, atol=1e-6)
    assert np.all(layer[60:] == 0)                      # past the top of the cutout: no reflection
    assert np.all(layer[40:60, :20] == 0) and np.all(layer[40:60, 44:] == 0)
    below = np.broadcast_to(np.arange(64)[:, None] + 0.5 > cam.horizon, (64, 64))
    assert np.all(r["spp"][below] == 1)   # one sample per mirror pixel


def test_planar_closed_form_equals_traced_mirror(device):
    for seed in range(3):
        cam, cut, fg, bg = upright_scene(seed=seed)
        rng = np.random.default_rng(seed)
        # a lumpy, leaning object: heights no longer a clean flip
        fg = np.where(cut[..., 3] > 0, fg + rng.uniform(0, 6, fg.shape), 0).astype(np.float32)
        traced = R.reflection_cl(device, cam, cut, fg, bg, planar=False)
        closed = R.reflection_cl(device, cam, cut, fg, bg, planar=True)
        below = np.broadcast_to(np.arange(64)[:, None] + 0.5 > cam.horizon, (64, 64))
        np.testing.assert_array_equal(closed["planar"], below)
        np.testing.assert_allclose(closed["layer"], traced["layer"], atol=1e-6)


def test_planar_closed_form_used_only_on_flat_ground(device):
    cam, cut, fg, bg = upright_scene()
    bg[:, 50:] = np.maximum(0, 30.0 - np.arange(64))[:, None]    # a wall on the right
    r = R.reflection_cl(device, cam, cut, fg, bg, planar=True)
    assert r["planar"][9:, :48].all() and r["planar"][32:, 51:].all()
    assert not r["planar"][:30, 50:].any() and not r["planar"][:8].any()


@pytest.mark.parametrize("eta", [1.0, 1.33, 1.5, 2.42])
def test_fresnel_normal_and_grazing_incidence(eta):
    assert R.fresnel_dielectric(1.0, eta) == pytest.approx(((1 - eta) / (1 + eta)) ** 2, abs=1e-12)
    c = np.linspace(1e-6, 1.0, 200)
    F = R.fresnel_dielectric(c, eta)
    if eta > 1:
        assert R.fresnel_dielectric(1e-6, eta) > 0.999
        assert np.all(np.diff(F) <= 1e-12)           # decreasing toward normal incidence
    # Schlick with f0 = the normal-incidence value agrees at both ends
    f0 = ((1 - eta) / (1 + eta)) ** 2
    assert R.fresnel_schlick(1.0, [f0] * 3)[0] == pytest.approx(f0)
    assert R.fresnel_schlick(0.0, [f0] * 3)[0] == pytest.approx(1.0)


def test_fresnel_total_internal_reflection():
    # from glass into air (eta = 1/1.5): critical angle asin(1/1.5)
    crit = math.cos(math.asin(1 / 1.5))
    assert R.fresnel_dielectric(crit - 1e-3, 1 / 1.5) == 1.0
    assert R.fresnel_dielectric(crit + 1e-2, 1 / 1.5) < 1.0


def _random_wo(n, rng, min_cos=0.02):
    ct = rng.uniform(min_cos, 1.0, n)
    ph = rng.uniform(0, 2 * math.pi, n)
    st = np.sqrt(1 - ct * ct)
    return np.stack([st * np.cos(ph), st * np.sin(ph), ct], -1)


@pytest.mark.parametrize("alpha", [0.05, 0.3, 0.8])
def test_ggx_samples_never_below_surface(alpha):
    rng = np.random.default_rng(0)
    wo = _random_wo(50000, rng)
    wil, w = R.ggx_sample_weight(wo, alpha, rng.random(50000), rng.random(50000))
    traced = np.any(w > 0, axis=-1)
    assert np.all(wil[traced, 2] > 0)
    assert traced.mean() > 0.6                     # most samples are kept


def _albedo_quadrature(alpha, cos_o, n_t=600, n_p=400):
    """Directional albedo of the GGX specular BRDF with F = 1 by midpoint quadrature
    over the hemisphere: integral of D G2 / (4 cos_o) over incoming directions."""
    wo = np.array([math.sqrt(1 - cos_o ** 2), 0.0, cos_o])
    t = (np.arange(n_t) + 0.5) * (math.pi / 2) / n_t
    p = (np.arange(n_p) + 0.5) * 2 * math.pi / n_p
    T, P = np.meshgrid(t, p, indexing="ij")
    wi = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1)
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    D = R.ggx_d(h[..., 2], alpha)
    G2 = 1.0 / (1.0 + R.smith_lambda(cos_o, alpha) + R.smith_lambda(wi[..., 2], alpha))
    f_cos = D * G2 / (4 * cos_o)                       # f * cos_i, cos_i cancels
    return float(np.sum(f_cos * np.sin(T)) * (math.pi / 2 / n_t) * (2 * math.pi / n_p))


@pytest.mark.parametrize("alpha,cos_o", [(0.1, 0.9), (0.3, 0.5), (0.6, 0.8), (0.6, 0.2), (0.9, 0.6)])
def test_ggx_estimator_mean_is_the_albedo(alpha, cos_o):
    """White furnace: with F = 1 and a constant environment of 1, the sample mean of
    the estimator weight (VNDF sampling, rejected below-surface samples count 0)
    equals the BRDF's directional albedo from an independent quadrature."""
    rng = np.random.default_rng(1)
    n = 400000
    wo = np.tile([math.sqrt(1 - cos_o ** 2), 0.0, cos_o], (n, 1))
    _, w = R.ggx_sample_weight(wo, alpha, rng.random(n), rng.random(n), conductor=True, f0=(1, 1, 1))
    est = w[:, 0]
    ref = _albedo_quadrature(alpha, cos_o)
    se = est.std() / math.sqrt(n)
    assert abs(est.mean() - ref) < 4 * se + 2e-3, (est.mean(), ref, se)
    assert ref <= 1.0 + 1e-3


def test_kernel_rng_and_sampler_match_numpy(device):
    """Same random numbers and the same GGX sampler on the device: the glossy
    reflection kernel agrees with the numpy reference pixel by pixel."""
    cam, cut, fg, bg = upright_scene(W=48, H=48, foot=30.25, rows=(12, 30), cols=(14, 34))
    for rough, cond in ((0.3, False), (0.6, True)):
        cl = R.reflection_cl(device, cam, cut, fg, bg, roughness=rough, conductor=cond,
                             f0=(0.9, 0.6, 0.5), min_spp=8, max_spp=8, seed=7)
        ref = R.reflection_numpy(cam, cut, fg, bg, roughness=rough, conductor=cond,
                                 f0=(0.9, 0.6, 0.5), spp=8, seed=7)
        err = np.abs(cl["layer"] - ref)
        # float32 vs float64 directions may flip a hit that grazes a surface sample
        assert (err.max(-1) > 1e-4).mean() < 0.002
        assert err.mean() < 1e-4
        assert ref[..., 3].max() > 0.05


def test_uvh_direction_is_the_projection_of_the_3d_ray():
    cam = Camera(200, 150, hfov=60, horizon=30.0, cam_height=1.3)
    rng = np.random.default_rng(3)
    P = np.stack([rng.uniform(-2, 2, 50), rng.uniform(0, 1.5, 50), rng.uniform(-8, -1, 50)], -1)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    p0, D0 = cam.project(P)
    e, s_max = R.uvh_direction(cam, p0, d)
    for t in (0.1, 0.5, 2.0):
        Q = P + t * d
        q, D = cam.project(Q)
        ahead = D > 0
        s = t / (D0 - t * d[:, 2])
        np.testing.assert_allclose(q[ahead], (p0 + s[:, None] * e)[ahead], rtol=1e-9, atol=1e-7)
        assert np.all(s[ahead] <= s_max[ahead] + 1e-12)
    away = d[:, 2] < 0
    vp, _ = cam.direction_to_image(d[away])
    end = p0[away] + s_max[away, None] * e[away]
    np.testing.assert_allclose(end[:, :2], vp, rtol=1e-9, atol=1e-6)      # ends at the vanishing point
    np.testing.assert_allclose(end[:, 1] + end[:, 2], cam.horizon, atol=1e-6)  # whose foot is on the horizon


def random_scene(rng, W, H):
    """Random blobs of random heights (some tall, some thin), for tracer comparisons."""
    mask = np.zeros((H, W), np.float32)
    fg = np.zeros((H, W), np.float32)
    for _ in range(rng.integers(1, 5)):
        i0, j0 = rng.integers(0, H - 4), rng.integers(0, W - 4)
        h, w = rng.integers(2, H // 2), rng.integers(2, W // 2)
        mask[i0:i0 + h, j0:j0 + w] = 1
        blk = fg[i0:i0 + h, j0:j0 + w]
        blk[...] = rng.uniform(0, 40) - rng.uniform(0, 1) * np.arange(blk.shape[0])[:, None] \
            + rng.uniform(0, 3, blk.shape)
    return march.surface_buffer(mask, fg)


def random_rays(rng, W, H, n, surf):
    """Half the rays in random directions, half aimed near a random surface point."""
    p0 = np.stack([rng.integers(0, W, n) + 0.5, rng.integers(0, H, n) + 0.5, rng.uniform(-5, 30, n)], 1)
    e = rng.normal(size=(n, 3))
    e[:, 2] *= rng.uniform(0.05, 1.0, n)
    i, j = np.nonzero(surf > march.NO_SURFACE_TEST)
    pick = rng.integers(0, i.size, n // 2)
    target = np.stack([j[pick] + rng.random(n // 2), i[pick] + rng.random(n // 2),
                       surf[i[pick], j[pick]] + rng.normal(0, 2, n // 2)], 1)
    e[: n // 2] = (target - p0[: n // 2]) * rng.uniform(0.2, 3, (n // 2, 1))
    s_max = np.where(rng.random(n) < 0.5, rng.uniform(3, 80, n) / np.abs(e[:, :2]).max(1), R.UNBOUNDED)
    return p0, e, s_max


@pytest.mark.parametrize("seed", range(6))
def test_hiz_march_same_hits_as_plain(device, seed):
    rng = np.random.default_rng(seed)
    W, H = int(rng.integers(40, 140)), int(rng.integers(40, 140))
    surf = random_scene(rng, W, H)
    p0, e, s_max = random_rays(rng, W, H, 4000, surf)
    thickness = float(rng.uniform(0.5, 8))
    plain = R.trace_rays_cl(device, surf, p0, e, s_max, thickness, hiz=False, clip_box=False)
    hiz = R.trace_rays_cl(device, surf, p0, e, s_max, thickness, hiz=True, clip_box=False)
    boxed = R.trace_rays_cl(device, surf, p0, e, s_max, thickness, hiz=True, clip_box=True)
    np.testing.assert_array_equal(hiz[0], plain[0])
    np.testing.assert_array_equal(boxed[0], plain[0])
    # the fallback pixel (last sample in the image) is the same too, without the box
    np.testing.assert_array_equal(hiz[1], plain[1])
    assert (plain[0] >= 0).mean() > 0.15
    assert hiz[2].mean() < plain[2].mean()
    # numpy reference (plain marching) agrees
    m, ok = R.setup_rays(p0, e, s_max, W, H)
    ref_hit, ref_last = R.trace_closest(surf, m, ok, thickness)
    assert (ref_hit != plain[0]).mean() < 0.002


def test_hiz_skips_empty_space_in_log_steps(device):
    """A ray through an empty 1024-wide image costs a few dozen steps, not 1000."""
    W, H = 1024, 64
    surf = np.full((H, W), march.NO_SURFACE, np.float32)
    surf[30:34, 1000:1004] = 5.0
    p0 = np.array([[0.5, 32.5, 4.5]])
    e = np.array([[1.0, 0.0, 0.0]])
    plain = R.trace_rays_cl(device, surf, p0, e, [R.UNBOUNDED], 1.0, hiz=False, clip_box=False)
    hiz = R.trace_rays_cl(device, surf, p0, e, [R.UNBOUNDED], 1.0, hiz=True, clip_box=False)
    assert plain[0][0] == hiz[0][0] == 32 * W + 1000
    assert plain[2][0] == 1000 and hiz[2][0] < 60


def test_adaptive_sampling_spends_samples_where_needed(device):
    cam, cut, fg, bg = upright_scene()
    loose = R.reflection_cl(device, cam, cut, fg, bg, roughness=0.4, min_spp=8, max_spp=512, target_se=0.01)
    tight = R.reflection_cl(device, cam, cut, fg, bg, roughness=0.4, min_spp=8, max_spp=512, target_se=0.002)
    ref = R.reflection_cl(device, cam, cut, fg, bg, roughness=0.4, min_spp=2048, max_spp=2048, seed=99)
    valid = np.broadcast_to(np.arange(64)[:, None] + 0.5 > cam.horizon, (64, 64))
    far = np.zeros((64, 64), bool)
    far[:, :6] = True                                   # far from the reflection: nothing to find
    # far from any hit: only the probe's samples
    empty = loose["spp"][valid & far & (ref["layer"][..., 3] == 0)]
    assert (empty == 4).mean() > 0.9 and empty.max() <= 8
    assert np.all(loose["spp"][~valid] == 0)
    assert tight["spp"].sum() > 2 * loose["spp"].sum()
    assert tight["spp"].max() <= 512
    rmse = lambda a: float(np.sqrt(np.mean((a["layer"] - ref["layer"]) ** 2)))
    assert rmse(tight) < rmse(loose)
    assert rmse(tight) < 0.004


def test_conductor_tint_and_strength(device):
    cam, cut, fg, bg = upright_scene()
    a = R.reflection_cl(device, cam, cut, fg, bg, conductor=True, f0=(1.0, 0.5, 0.25), strength=0.5)
    L = a["layer"][40:60, 20:44]
    cos_o = np.clip(-R.view_directions(cam)[40:60, 20:44, 1], 0, 1)
    w = R.fresnel_schlick(cos_o, (1.0, 0.5, 0.25))
    src = cut[79 - np.arange(40, 60)][:, 20:44]
    np.testing.assert_allclose(L[..., :3], 0.5 * w * src[..., :3], atol=1e-6)
    np.testing.assert_allclose(L[..., 3], 0.5 * w.mean(-1) * src[..., 3], atol=1e-6)


def test_empty_cutout_gives_empty_layer(device):
    cam, cut, fg, bg = upright_scene()
    r = R.reflection_cl(device, cam, np.zeros_like(cut), fg, bg, roughness=0.5)
    assert not r["layer"].any()


def test_glossy_reflection_same_with_and_without_pyramid(device):
    cam, cut, fg, bg = upright_scene()
    bg[:, 50:] = np.maximum(0, 30.0 - np.arange(64))[:, None]
    a = R.reflection_cl(device, cam, cut, fg, bg, roughness=0.5, min_spp=16, max_spp=16, hiz=True)
    b = R.reflection_cl(device, cam, cut, fg, bg, roughness=0.5, min_spp=16, max_spp=16, hiz=False)
    np.testing.assert_array_equal(a["layer"], b["layer"])
    assert a["steps"].sum() < b["steps"].sum()


def test_low_discrepancy_samples_fill_the_square():
    """The per-pixel R2 points are far more even than independent random numbers:
    over 1024 points every cell of an 8 x 8 grid holds 16 +- 3 points."""
    for pix in (0, 17, 123456):
        u1, u2 = R.sample2(5, np.full(1024, pix), np.arange(1024))
        assert u1.min() >= 0 and u1.max() < 1 and u2.min() >= 0 and u2.max() < 1
        counts = np.histogram2d(u1, u2, bins=8, range=[[0, 1], [0, 1]])[0]
        assert counts.min() >= 13 and counts.max() <= 19
        assert abs(u1.mean() - 0.5) < 2e-3 and abs(u2.mean() - 0.5) < 2e-3


def test_hiz_skips_runs_far_behind_the_surface(device):
    """A ray passing behind a wide, tall wall (beyond its thickness) skips it in
    coarse tiles too, and hits a surface it reaches afterwards at the same pixel."""
    W, H = 1024, 64
    surf = np.full((H, W), march.NO_SURFACE, np.float32)
    surf[:, 100:900] = 200.0                     # far above the ray: it passes behind
    surf[30:34, 1000:1004] = 5.0
    p0 = np.array([[0.5, 32.5, 4.5]])
    e = np.array([[1.0, 0.0, 0.0]])
    plain = R.trace_rays_cl(device, surf, p0, e, [R.UNBOUNDED], 1.0, hiz=False, clip_box=False)
    hiz = R.trace_rays_cl(device, surf, p0, e, [R.UNBOUNDED], 1.0, hiz=True, clip_box=False)
    assert plain[0][0] == hiz[0][0] == 32 * W + 1000
    assert hiz[2][0] < 100 < plain[2][0]


@pytest.mark.parametrize("case", ["border", "tall", "nan", "wall", "horizon_low", "grazing"])
def test_reflection_stays_finite_in_hard_cases(device, case):
    """Cutouts touching the image border, taller than the image, NaN heights,
    walls, a horizon inside the floor and grazing views: finite, premultiplied
    (colour <= alpha for white cutouts), and the kernel agrees with the reference."""
    cam, cut, fg, bg = upright_scene()
    if case == "border":
        cut[:, :, :] = 0
        cut[0:40, 0:30, :] = 1.0
        fg[:] = 0
        fg[0:40, 0:30] = 40.25 - (np.arange(0, 40)[:, None] + 0.5)
    elif case == "tall":
        fg = np.where(cut[..., 3] > 0, fg + 500.0, 0).astype(np.float32)
    elif case == "nan":
        fg[25:30, 25:30] = np.nan
        bg[50:52, 10:20] = np.nan
    elif case == "wall":
        bg = np.maximum(0.0, 35.0 - np.arange(64))[:, None].repeat(64, 1).astype(np.float32)
    elif case == "horizon_low":
        cam = Camera(64, 64, hfov=50.0, horizon=45.0)
    elif case == "grazing":
        cam = Camera(64, 64, hfov=170.0, horizon=8.0)
    cut[..., :3] = cut[..., 3:]                       # white: colour == alpha
    for rough in (0.0, 0.5):
        r = R.reflection_cl(device, cam, cut, fg, bg, roughness=rough, min_spp=8, max_spp=8, planar=False)
        L = r["layer"]
        assert np.isfinite(L).all()
        assert L.min() >= 0 and L[..., 3].max() <= 1.0
        assert np.all(L[..., :3] <= L[..., 3:] + 1e-6)
        ref = R.reflection_numpy(cam, cut, fg, bg, roughness=rough, spp=8)
        assert (np.abs(L - ref).max(-1) > 1e-4).mean() < 0.01
