"""GaussianBlur: OpenCL kernel vs numpy reference vs kornia, and the node in a graph."""
import numpy as np
import pytest
import torch
import kornia

from pixgraph_nodes.ops.blur import gaussian_blur, gaussian_blur_reference, gaussian_kernel1d


def test_kernel_weights_are_normalised_gaussian():
    w = gaussian_kernel1d(2.0)
    assert len(w) == 2 * 6 + 1
    assert w.sum() == pytest.approx(1.0, abs=1e-6)
    # ratio of neighbouring taps is exp(-(2k+1)/(2 sigma^2))
    assert w[7] / w[6] == pytest.approx(np.exp(-1 / 8), rel=1e-5)


def test_reference_preserves_constant_and_mass():
    img = np.full((9, 11, 3), 0.25, np.float32)
    np.testing.assert_allclose(gaussian_blur_reference(img, 3.0), 0.25, atol=1e-6)
    # an impulse far from the borders spreads into the separable kernel's outer product
    imp = np.zeros((41, 41), np.float32)
    imp[20, 20] = 1.0
    out = gaussian_blur_reference(imp, 2.5)
    w = gaussian_kernel1d(2.5)
    r = len(w) // 2
    np.testing.assert_allclose(out[20 - r:21 + r, 20 - r:21 + r], np.outer(w, w), atol=1e-7)
    assert out.sum() == pytest.approx(1.0, abs=1e-5)


@pytest.mark.parametrize("sigma,shape", [(0.7, (17, 23, 4)), (2.0, (32, 40)), (5.0, (20, 64, 3))])
def test_opencl_matches_numpy_reference(device, sigma, shape):
    img = np.random.default_rng(3).uniform(0, 1, shape).astype(np.float32)
    ours = gaussian_blur(device, img, sigma)
    assert ours.shape == img.shape and ours.dtype == np.float32
    np.testing.assert_allclose(ours, gaussian_blur_reference(img, sigma), atol=2e-6)


@pytest.mark.parametrize("sigma", [0.8, 1.5, 3.0])
def test_opencl_matches_kornia(device, sigma):
    img = np.random.default_rng(4).uniform(0, 1, (24, 30, 3)).astype(np.float32)
    k = len(gaussian_kernel1d(sigma))
    t = torch.from_numpy(img).permute(2, 0, 1)[None]
    ref = kornia.filters.gaussian_blur2d(t, (k, k), (sigma, sigma), border_type="replicate")
    ref = ref[0].permute(1, 2, 0).numpy()
    np.testing.assert_allclose(gaussian_blur(device, img, sigma), ref, atol=1e-5)


def test_sigma_zero_is_identity(device):
    img = np.random.default_rng(5).uniform(0, 1, (5, 6)).astype(np.float32)
    np.testing.assert_array_equal(gaussian_blur(device, img, 0.0), img)
