"""Weight averages of cutout-height networks (lab/height/soup.py; docs/height-record.md,
"Rules fixed before measuring: weight averages of the seventh")."""
import numpy as np
import pytest

torch = pytest.importorskip("torch")

from pixgraph_lab.height.soup import average_states, pull_toward, recalibrate_bn  # noqa: E402
from pixgraph_nodes.ops.learned_height import build_model  # noqa: E402


def _states(n, base=4, levels=2):
    out = []
    for seed in range(n):
        torch.manual_seed(seed)
        m = build_model(base, levels, 3)
        for b in m.modules():                      # distinct BatchNorm statistics too
            if isinstance(b, torch.nn.BatchNorm2d):
                b.running_mean.uniform_(-1, 1)
                b.num_batches_tracked.fill_(7 + seed)
        out.append(m.state_dict())
    return out


def test_average_and_pull_are_the_weighted_means():
    a, b, c = _states(3)
    avg = average_states([a, b, c])
    k = "down.0.0.weight"
    assert torch.allclose(avg[k], (a[k] + b[k] + c[k]) / 3, atol=1e-7)
    w = average_states([a, b], [0.25, 0.75])
    assert torch.allclose(w[k], 0.25 * a[k] + 0.75 * b[k], atol=1e-7)
    assert int(avg["down.0.1.num_batches_tracked"]) == 7          # integers: the first member's
    assert torch.equal(pull_toward(a, b, 1.0)[k], b[k]) and torch.equal(pull_toward(a, b, 0.0)[k], a[k])
    assert torch.allclose(pull_toward(a, b, 0.5)[k], average_states([a, b])[k], atol=1e-7)
    with pytest.raises(ValueError, match="sum to 1"):
        average_states([a, b], [0.5, 0.6])
    other = build_model(6, 2, 3).state_dict()
    with pytest.raises(ValueError, match="not the same network"):
        average_states([a, other])


def test_batchnorm_is_re_estimated_as_the_mean_over_the_crops():
    """After ``recalibrate_bn`` the first BatchNorm's running mean is the mean of its
    inputs over every crop it saw (equal batches: the mean of the batch means), and
    its running variance the mean of the batch variances; the weights are untouched."""
    torch.manual_seed(0)
    model = build_model(4, 2, 3)
    before = {k: v.clone() for k, v in model.state_dict().items() if "running" not in k and "num_batches" not in k}
    rng = np.random.default_rng(1)
    N, S = 40, 32
    x = rng.random((N, 6, S, S)).astype(np.float32)
    x[:, 3] = (x[:, 3] > 0.3)                      # alpha
    x[:, :3] *= x[:, 3:4]                          # premultiplied colour
    x[:, 5] = np.linspace(-1, 1, S)[None, :, None]  # the row channel: a vertical ramp
    t = rng.random((N, S, S)).astype(np.float32)
    w = x[:, 3].copy()
    seen = []
    bn = model.down[0][1]
    hook = bn.register_forward_hook(lambda m, inp, out: seen.append(inp[0].detach().clone()))
    used = recalibrate_bn(model, x, t, w, crops=32, batch=8, seed=3)
    hook.remove()
    assert used == 32 and len(seen) == 4
    means = torch.stack([s.mean((0, 2, 3)) for s in seen])
    varis = torch.stack([s.var((0, 2, 3), unbiased=True) for s in seen])
    assert torch.allclose(bn.running_mean, means.mean(0), atol=1e-5)
    assert torch.allclose(bn.running_var, varis.mean(0), rtol=1e-4, atol=1e-6)
    assert bn.momentum == 0.1 and not model.training
    for k, v in model.state_dict().items():
        if k in before:
            assert torch.equal(v, before[k]), k
