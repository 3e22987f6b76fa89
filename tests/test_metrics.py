"""lab/metrics.py against independent implementations and analytic cases."""
import numpy as np
import pytest

from pixgraph_lab import metrics as M


def _pair(seed=0, shape=(48, 40)):
    rng = np.random.default_rng(seed)
    g = np.clip(rng.random(shape) * 0.3 + np.linspace(0, 0.7, shape[1])[None], 0, 1)
    p = np.clip(g + rng.normal(0, 0.1, shape), 0, 1)
    return p, g


def test_identical_images():
    _, g = _pair()
    assert M.rmse(g, g) == 0.0
    assert M.rmse_s(g, g) == pytest.approx(0.0, abs=1e-12)
    assert M.ssim(g, g) == pytest.approx(1.0, abs=1e-12)
    assert M.zncc(g, g) == pytest.approx(1.0, abs=1e-12)


def test_rmse_and_scaled_prediction():
    p, g = _pair(1)
    assert M.rmse(p, g) == pytest.approx(np.sqrt(np.mean((p - g) ** 2)), rel=1e-12)
    # p = 2 g: RMSE-s is 0 (s = 1/2), plain RMSE is the RMS of g
    assert M.rmse_s(2 * g, g) == pytest.approx(0.0, abs=1e-12)
    assert M.rmse(2 * g, g) == pytest.approx(np.sqrt(np.mean(g ** 2)), rel=1e-12)
    # ZNCC is invariant to positive affine maps, flips sign for negative ones
    assert M.zncc(3 * p + 0.2, g) == pytest.approx(M.zncc(p, g), rel=1e-10)
    assert M.zncc(-p, g) == pytest.approx(-M.zncc(p, g), rel=1e-10)


def test_rmse_s_against_lstsq_and_zero_prediction():
    p, g = _pair(2)
    s, *_ = np.linalg.lstsq(p.reshape(-1, 1), g.ravel(), rcond=None)
    ref = np.sqrt(np.mean((s[0] * p - g) ** 2))
    assert M.rmse_s(p, g) == pytest.approx(ref, rel=1e-10)
    assert M.rmse_s(p, g) <= M.rmse(p, g) + 1e-15     # the optimal scale never hurts
    z = np.zeros_like(g)
    assert M.rmse_s(z, g) == pytest.approx(np.sqrt(np.mean(g ** 2)), rel=1e-12)


def test_zncc_against_numpy_and_constant():
    p, g = _pair(3)
    assert M.zncc(p, g) == pytest.approx(np.corrcoef(p.ravel(), g.ravel())[0, 1], rel=1e-10)
    assert M.zncc(np.full_like(g, 0.3), g) == 0.0
    assert M.zncc(g, np.zeros_like(g)) == 0.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ssim_matches_scikit_image(seed):
    skm = pytest.importorskip("skimage.metrics")
    p, g = _pair(seed, shape=(37, 53))
    ref = skm.structural_similarity(p, g, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                    data_range=1.0)
    assert M.ssim(p, g) == pytest.approx(ref, abs=1e-10)
    # sanity: the noisy pair is clearly below 1
    assert M.ssim(p, g) < 0.95


def test_ssim_map_matches_scikit_image_full():
    skm = pytest.importorskip("skimage.metrics")
    p, g = _pair(4, shape=(30, 30))
    _, S = skm.structural_similarity(p, g, gaussian_weights=True, sigma=1.5, use_sample_covariance=False,
                                     data_range=1.0, full=True)
    np.testing.assert_allclose(M.ssim_map(p, g), S, atol=1e-10)


def test_gaussian_window_is_11_taps():
    k = M.gaussian_kernel()
    assert k.shape == (11,)
    assert k.sum() == pytest.approx(1.0)
    assert k[5] == k.max()


def test_valid_mask_excludes_pixels():
    p, g = _pair(5)
    valid = np.ones(g.shape, bool)
    valid[10:20, 10:25] = False
    q = p.copy()
    q[~valid] = 1.0 - g[~valid]                      # garbage inside the excluded region
    # RMSE, RMSE-s and ZNCC only see the valid pixels
    assert M.rmse(q, g, valid) == pytest.approx(np.sqrt(np.mean((p[valid] - g[valid]) ** 2)), rel=1e-12)
    assert M.rmse_s(q, g, valid) == pytest.approx(M.rmse_s(p[valid], g[valid]), rel=1e-12)
    assert M.zncc(q, g, valid) == pytest.approx(np.corrcoef(p[valid], g[valid])[0, 1], rel=1e-10)
    # SSIM: excluded pixels are set equal, so the garbage cannot change the score
    assert M.ssim(q, g, valid) == pytest.approx(M.ssim(p, g, valid), abs=1e-12)
    # and an image that differs only inside the excluded region scores perfectly
    r = g.copy()
    r[~valid] = 0.0
    assert M.ssim(r, g, valid) == pytest.approx(1.0, abs=1e-12)
    assert M.rmse(r, g, valid) == 0.0


def test_ssim_against_brute_force_window():
    # an independent direct evaluation at one interior pixel (no separable filter)
    p, g = _pair(6, shape=(25, 25))
    k = M.gaussian_kernel()
    w = np.outer(k, k)
    i, j = 12, 9
    P, G = p[i - 5:i + 6, j - 5:j + 6], g[i - 5:i + 6, j - 5:j + 6]
    mp, mg = (w * P).sum(), (w * G).sum()
    vp, vg = (w * P * P).sum() - mp ** 2, (w * G * G).sum() - mg ** 2
    cpg = (w * P * G).sum() - mp * mg
    c1, c2 = 0.01 ** 2, 0.03 ** 2
    ref = (2 * mp * mg + c1) * (2 * cpg + c2) / ((mp ** 2 + mg ** 2 + c1) * (vp + vg + c2))
    assert M.ssim_map(p, g)[i, j] == pytest.approx(ref, abs=1e-12)


def test_shadow_metrics_keys_and_shape_errors():
    p, g = _pair(7)
    out = M.shadow_metrics(p, g)
    assert set(out) == {"rmse", "rmse_s", "ssim", "zncc"}
    with pytest.raises(ValueError):
        M.rmse(p[:, :-1], g)
