"""The SSN++ training loss's structure terms (lab/ssn/train.py)."""
import numpy as np
import pytest

torch = pytest.importorskip("torch")

from pixgraph_lab import metrics  # noqa: E402
from pixgraph_lab.ssn import train  # noqa: E402


def _shadow(n=64, edge=20.0, width=3.0, seed=0):
    """A darkness ramp (a penumbra of ``width`` px at column ``edge``) plus noise."""
    x = np.arange(n)[None, :].repeat(n, 0)
    d = 1.0 / (1.0 + np.exp((x - edge) / width))
    return np.clip(d + np.random.default_rng(seed).normal(0, 0.02, d.shape), 0, 1)


def test_ssim_map_matches_the_benchmark_metric_inside_the_border():
    p, g = _shadow(edge=20, width=2, seed=1), _shadow(edge=23, width=5, seed=2)
    ref = metrics.ssim_map(p, g)
    got = train.ssim_map(torch.tensor(p, dtype=torch.float32)[None, None],
                         torch.tensor(g, dtype=torch.float32)[None, None], train._gauss_taps())[0, 0].numpy()
    r = 5   # the metric pads symmetrically, the loss with zeros: compare where neither pads
    assert np.abs(got[r:-r, r:-r] - ref[r:-r, r:-r]).max() < 1e-3   # float32 variances
    assert ref[r:-r, r:-r].min() < 0.9          # the two really differ


def test_structure_loss_is_zero_for_the_target_and_ignores_pixels_that_do_not_count():
    g = torch.tensor(_shadow(), dtype=torch.float32)[None]
    w = torch.ones_like(g)
    w[:, 30:40, 30:40] = 0                       # the cutout
    pred = g[:, None].clone()
    assert train.structure_loss(pred, g, w, 1.0, 1.0).item() == pytest.approx(0.0, abs=1e-6)
    pred[:, :, 30:40, 30:40] = 0.7               # anything inside the cutout
    assert train.structure_loss(pred, g, w, 1.0, 1.0).item() == pytest.approx(0.0, abs=1e-6)


def test_structure_terms_punish_streaks_that_l1_and_l2_do_not_see():
    """Streaks (+-a in alternate 2-px bands) and a uniform offset of +a have the
    same |error| at every pixel, so L1 + L2 cannot tell them apart; the SSIM and
    gradient terms must rank the streaks worse."""
    g = torch.tensor(_shadow(edge=30, width=3.0, seed=0) * 0.8 + 0.1, dtype=torch.float32)[None]
    w = torch.ones_like(g)
    a = 0.05
    bands = torch.where((torch.arange(64) // 2) % 2 == 0, a, -a).view(1, 1, 1, 64)
    streaks = g[:, None] + bands
    offset = g[:, None] + a
    assert train.masked_loss(streaks, g, w).item() == pytest.approx(train.masked_loss(offset, g, w).item(), rel=1e-5)
    for ssim_w, grad_w in ((1.0, 0.0), (0.0, 1.0)):
        assert train.structure_loss(streaks, g, w, ssim_w, grad_w).item() > \
            1.5 * train.structure_loss(offset, g, w, ssim_w, grad_w).item()
    x = streaks.clone().requires_grad_()
    train.structure_loss(x, g, w, 1.0, 1.0).backward()
    assert torch.isfinite(x.grad).all() and x.grad.abs().sum() > 0
