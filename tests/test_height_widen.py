"""Widening the cutout-height U-Net (lab/height/widen.py) keeps what it computes."""
import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")
from pixgraph_lab.height.widen import widen_state  # noqa: E402
from pixgraph_nodes.ops.learned_height import WEIGHTS, build_model  # noqa: E402


@pytest.fixture(scope="module")
def shipped():
    ck = torch.load(WEIGHTS, map_location="cpu", weights_only=True)
    return {k: v.float() for k, v in ck["model"].items()}


#: the shipped network's base width (the seventh: 24, itself widened from the fifth's 16)
BASE = int(json.loads(torch.load(WEIGHTS, map_location="cpu", weights_only=True)["config"])["base"])


def _out(model, x):
    model.eval()
    with torch.no_grad():
        return model(x)


@pytest.mark.parametrize("extra", [0, 8, 16])
def test_the_wider_network_computes_the_same_heights(shipped, extra):
    new_base = BASE + extra
    small = build_model(BASE, 4, 3)
    small.load_state_dict(shipped)
    big = build_model(new_base, 4, 3)
    big.load_state_dict(widen_state(shipped, BASE, new_base, 4, noise=0.0, seed=1))
    x = torch.from_numpy(np.random.default_rng(0).random((3, 6, 64, 64), dtype=np.float32))
    a, b = _out(small, x), _out(big, x)
    assert float((a - b).abs().max()) < 1e-4 * float(a.abs().max())
    assert sum(p.numel() for p in big.parameters()) > sum(p.numel() for p in small.parameters()) or extra == 0


def test_noise_breaks_the_copies_but_stays_close(shipped):
    small = build_model(BASE, 4, 3)
    small.load_state_dict(shipped)
    big = build_model(BASE + 8, 4, 3)
    big.load_state_dict(widen_state(shipped, BASE, BASE + 8, 4, noise=0.01, seed=1))
    x = torch.from_numpy(np.random.default_rng(0).random((2, 6, 64, 64), dtype=np.float32))
    a, b = _out(small, x), _out(big, x)
    d = float((a - b)[:, 0].abs().mean())
    assert 0 < d < 0.05 * float(a[:, 0].abs().mean())


def test_a_wrong_division_is_caught(shipped, monkeypatch):
    # the check above can fail: copies read without dividing the next layer's weights
    import pixgraph_lab.height.widen as wd
    monkeypatch.setattr(wd.np, "bincount", lambda g, minlength: np.ones(minlength, np.int64))
    small = build_model(BASE, 4, 3)
    small.load_state_dict(shipped)
    big = build_model(BASE + 8, 4, 3)
    big.load_state_dict(wd.widen_state(shipped, BASE, BASE + 8, 4))
    x = torch.from_numpy(np.random.default_rng(0).random((1, 6, 64, 64), dtype=np.float32))
    assert float((_out(small, x) - _out(big, x)).abs().max()) > 1e-2
